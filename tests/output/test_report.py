"""What a run leaves to look at: plots.png of its metrics, and the page `run all` writes
(index.html): every file it names exists, and its table says what metrics.json says."""

import json
import shutil
from html.parser import HTMLParser

import numpy as np
import pytest
from PIL import Image

import taichi_dcd
from taichi_dcd.measure.penetration import verdict
from taichi_dcd.output.report import plot_run, write_index
from taichi_dcd.output.run import MANIFEST, run_scene
from taichi_dcd.scene.config import scene_from_dict
from taichi_dcd.scene.scene import Scene


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    """A 0.2 m box dropped from 1 cm onto a block, 8 frames, frames and GIF written."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)
    config = scene_from_dict({"sim": {"frame_dt": 0.01}, "body": [
        {"name": "block", "kind": "static", "shape": "box", "params": {"size": [1.0, 0.2, 1.0]},
         "position": [0.0, -0.1, 0.0]},
        {"name": "box", "kind": "rigid", "shape": "box", "params": {"size": [0.2, 0.2, 0.2]},
         "position": [0.0, 0.11, 0.0]}]}, name="drop")
    out = tmp_path_factory.mktemp("runs") / "drop"
    run_scene(Scene(config), out, frames=8, progress=None, render=True, gif=True, notices=None)
    return out


def test_a_run_writes_its_plots_and_owns_them(run_folder):
    """plots.png is a real image, and the run's manifest lists it (a rerun replaces it)."""
    with Image.open(run_folder / "plots.png") as image:
        assert image.size[0] >= 600 and image.size[1] >= 400
    assert "plots.png" in json.loads((run_folder / MANIFEST).read_text())["files"]


def test_plots_of_a_run_without_overlap_or_ending_in_an_explosion_are_drawn(tmp_path):
    """A run whose depth and volume are 0 in every frame, its energy infinite in the last one
    (a run that exploded), still gets its plots."""
    t = np.linspace(0.01, 0.5, 50)
    energy = np.exp(-t)
    energy[-1] = np.inf
    columns = {"time": t, "penetration_depth": np.zeros(50), "overlap_volume": np.zeros(50),
               "kinetic_energy": energy, "potential_energy": np.zeros(50), "contact_count": np.full(50, 3.0),
               "max_vertex_speed": np.zeros(50)}
    plot_run(columns, tmp_path / "plots.png", "still")
    with Image.open(tmp_path / "plots.png") as image:
        assert image.size[0] >= 600 and image.size[1] >= 400
    assert not (tmp_path / "plots.png.tmp").exists()


class Page(HTMLParser):
    """The links, image sources and table rows (cell texts) of a page."""

    def __init__(self):
        super().__init__()
        self.refs, self.rows, self._cell = [], [], None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "a" and not attrs.get("href", "#").startswith("#"):
            self.refs.append(attrs["href"])
        if tag == "img":
            self.refs.append(attrs["src"])
        if tag == "tr":
            self.rows.append([])
        if tag in ("td", "th"):
            self._cell = ""

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self.rows[-1].append(self._cell)
            self._cell = None


def test_the_page_names_only_files_that_exist_and_its_table_matches_the_metrics(run_folder, tmp_path):
    """Two scenes: the real run (8 frames, not settled: fails) and a copy whose metrics.json
    says it settled clean (passes). Every link and image on the page is a relative path to a
    file that exists; each table row holds its scene's verdict and figures from metrics.json."""
    root = tmp_path / "outputs"
    shutil.copytree(run_folder, root / "drop")
    shutil.copytree(run_folder, root / "rests")
    metrics = json.loads((root / "rests" / "metrics.json").read_text())
    metrics.update(settled=True, time_to_settle=0.05, final_penetration_depth=0.0, final_overlap_volume=0.0,
                   max_penetration_depth=2e-6)
    (root / "rests" / "metrics.json").write_text(json.dumps(metrics))
    page = Page()
    page.feed(write_index(root, ["drop", "rests"]).read_text(encoding="utf-8"))
    assert page.refs
    for ref in page.refs:
        assert "://" not in ref and not ref.startswith("/"), ref
        assert (root / ref).is_file(), ref
    assert {"drop/animation.gif", "drop/plots.png", "rests/plots.png"} <= set(page.refs)
    header, *rows = page.rows
    assert header[:2] == ["scene", "verdict"] and len(rows) == 2
    for row, name in zip(rows, ["drop", "rests"]):
        m = json.loads((root / name / "metrics.json").read_text())
        assert row[0] == name
        assert row[1] == (verdict(m) or "pass")
        assert float(row[2]) == pytest.approx(m["final_penetration_depth"], rel=1e-2, abs=0.0)
        assert float(row[3]) == pytest.approx(m["max_penetration_depth"], rel=1e-2, abs=0.0)
        assert float(row[4]) == pytest.approx(m["final_overlap_volume"], rel=1e-2, abs=0.0)
        assert int(row[6]) == m["frames"]
    assert rows[0][1] == "not settled" and rows[1][1] == "pass"
