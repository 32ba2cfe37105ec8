"""What a run leaves to look at besides frames: plots.png (depth, overlap volume, kinetic energy
and contact count against time, the contact test's limits drawn) and, for `run all`, one
self-contained HTML page (index.html) with the verdict table, each scene's animation or last
frame, and its plots."""

from __future__ import annotations

import html
import json
import os
from pathlib import Path

import numpy as np

from ..measure.penetration import PASS_FINAL_DEPTH, PASS_FINAL_OVERLAP, PASS_MAX_DEPTH, PASS_MAX_SELF_DEPTH, verdict
from .render import last_frame

PLOTS = "plots.png"
INDEX = "index.html"


def plot_run(columns: dict[str, np.ndarray], path: Path, title: str, length_scale: float = 1.0) -> None:
    """Write plots.png: four panels against time (s): penetration depth (m) with the limits on
    the deepest and the final depth (with soft bodies also their deepest crossing of themselves,
    dotted: its limit), overlap volume (m³) with its final limit, kinetic energy
    (J) and contact rows. Depths, volumes and energies on log axes (zeros and non-finite
    values are left out: a run without any overlap shows an empty panel with its limits).
    Written to a temporary name and renamed."""
    # The figure without pyplot, laid out by hand: tight_layout doubled the ~0.3 s a run's
    # plots cost, which every run (and every test that runs a scene) pays.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t = columns["time"]
    fig = Figure(figsize=(10, 6.5))
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2, sharex=True)
    panels = [
        (axes[0, 0], "penetration_depth", "penetration depth (m)",
         [(PASS_MAX_DEPTH * length_scale, "deepest allowed"), (PASS_FINAL_DEPTH * length_scale, "final allowed")]),
        (axes[0, 1], "overlap_volume", "overlap volume (m³)",
         [(PASS_FINAL_OVERLAP * length_scale ** 3, "final allowed")]),
        (axes[1, 0], "kinetic_energy", "kinetic energy (J)", []),
    ]
    for ax, key, label, limits in panels:
        y = columns[key]
        shown = np.isfinite(y) & (y > 0.0)
        ax.plot(t[shown], y[shown], ".-", ms=2, lw=1, color="tab:blue")
        for value, name in limits:
            ax.axhline(value, color="tab:red", ls="--", lw=1)
            ax.annotate(name, (0.01, value), xycoords=("axes fraction", "data"), color="tab:red", fontsize=8,
                        va="bottom")
        if not shown.any():
            ax.text(0.5, 0.5, "0 in every frame", transform=ax.transAxes, ha="center", color="0.4")
        floor = [v for v in [*y[shown], *(value for value, _ in limits)] if v > 0.0]
        ax.set_yscale("log")
        if floor:
            ax.set_ylim(min(floor) / 10.0, max(floor) * 10.0)
        ax.set_ylabel(label)
        ax.grid(True, which="major", alpha=0.3)
    if "self_penetration_depth" in columns:
        # A soft body's crossings of itself, beside the depth between bodies.
        ax = axes[0, 0]
        y = columns["self_penetration_depth"]
        shown = np.isfinite(y) & (y > 0.0)
        ax.plot(t[shown], y[shown], ".-", ms=2, lw=1, color="tab:orange", label="soft body through itself")
        ax.axhline(PASS_MAX_SELF_DEPTH * length_scale, color="tab:orange", ls=":", lw=1)
        if shown.any():
            low, high = ax.get_ylim()
            ax.set_ylim(min(low, y[shown].min() / 10.0), max(high, y[shown].max() * 10.0))
        ax.legend(loc="lower right", fontsize=8)
    ax = axes[1, 1]
    ax.step(t, columns["contact_count"], where="post", lw=1, color="tab:green")
    ax.set_ylabel("contact rows")
    ax.grid(True, alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(title)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.08, top=0.93, wspace=0.28, hspace=0.1)
    tmp = path.with_name(path.name + ".tmp")
    fig.savefig(tmp, dpi=80, format="png")
    os.replace(tmp, path)


def _cell(value, fmt: str = "{:.2e}") -> str:
    return "—" if value is None else html.escape(fmt.format(value))


def scene_picture(folder: Path) -> str | None:
    """The picture the page shows for a run folder, relative to it: animation.gif, else the
    last frame, else None."""
    if (folder / "animation.gif").is_file():
        return "animation.gif"
    frame = last_frame(folder / "frames")
    return f"frames/{frame.name}" if frame is not None else None


def write_index(root: Path, scenes: list[str]) -> Path:
    """Write root/index.html for the run folders root/<scene>: a table of each scene's verdict
    (its limits scaled by the run's length scale) and figures from metrics.json, then per scene
    its picture (scene_picture) and plots.png. Links are relative; the page loads nothing from
    the network. Returns its path."""
    rows, sections = [], []
    for name in scenes:
        folder = root / name
        metrics = json.loads((folder / "metrics.json").read_text(encoding="utf-8"))
        fails = verdict(metrics, metrics.get("settings", {}).get("length_scale", 1.0))
        link = html.escape(name)
        rows.append(
            f'<tr class="{"fail" if fails else "pass"}"><td><a href="#{link}">{link}</a></td>'
            f"<td>{html.escape(fails or 'pass')}</td>"
            f"<td>{_cell(metrics['final_penetration_depth'])}</td><td>{_cell(metrics['max_penetration_depth'])}</td>"
            f"<td>{_cell(metrics['final_overlap_volume'])}</td><td>{_cell(metrics.get('time_to_settle'), '{:.2f}')}</td>"
            f"<td>{metrics['frames']}</td><td>{_cell(metrics.get('wall_time_per_sim_second'), '{:.3f}')}</td></tr>")
        images = []
        picture = scene_picture(folder)
        if picture:
            images.append(f'<img src="{link}/{html.escape(picture)}" alt="{link}: {html.escape(picture)}">')
        if (folder / PLOTS).is_file():
            images.append(f'<img src="{link}/{PLOTS}" alt="{link}: plots">')
        sections.append(f'<section id="{link}"><h2>{link}</h2>\n<p>{html.escape(fails or "pass")}; '
                        f'<a href="{link}/metrics.json">metrics.json</a>, <a href="{link}/metrics.csv">metrics.csv</a>'
                        f"</p>\n{''.join(images)}</section>")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>taichi-dcd: run all</title>
<style>
body {{ font-family: sans-serif; margin: 2em; }}
table {{ border-collapse: collapse; }}
td, th {{ border: 1px solid #bbb; padding: 0.2em 0.6em; text-align: right; }}
td:first-child, td:nth-child(2) {{ text-align: left; }}
tr.fail td:nth-child(2) {{ color: #b00; font-weight: bold; }}
img {{ max-width: 48%; vertical-align: top; margin: 0.3em; }}
</style></head><body>
<h1>taichi-dcd: run all</h1>
<p>Penetration by the independent measure on the final meshes of each frame. A scene passes when it
settles with final depth ≤ {PASS_FINAL_DEPTH:g} m, final overlap ≤ {PASS_FINAL_OVERLAP:g} m³ and depth
≤ {PASS_MAX_DEPTH:g} m throughout (limits scaled with a scene's length scale).</p>
<table>
<tr><th>scene</th><th>verdict</th><th>final depth (m)</th><th>deepest (m)</th><th>final overlap (m³)</th>
<th>settled at (s)</th><th>frames</th><th>wall s per sim s</th></tr>
{chr(10).join(rows)}
</table>
{chr(10).join(sections)}
</body></html>
"""
    path = root / INDEX
    tmp = root / (INDEX + ".tmp")
    tmp.write_text(page, encoding="utf-8")
    os.replace(tmp, path)
    return path
