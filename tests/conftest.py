"""Shared fixtures: Taichi in debug mode (bounds checks), f64 unless a test asks for f32.

Whole-scene runs (hundreds of frames) use `f64_scene` and `scene_run`, without debug
mode: bounds checks make them ~4× slower, and every kernel they run is also run in
debug mode by the solver's and the collision tests."""

import numpy as np
import pytest

import taichi_dcd


@pytest.fixture(autouse=True, scope="session")
def crashes_name_the_python_line(request):
    """Importing Taichi replaces Python's fatal-signal handler with its own, whose report a
    test worker's output capture swallows: a worker that crashed in CI left no word. Put
    pytest's faulthandler (which writes past the capture) back in front of it."""
    import faulthandler

    import taichi  # noqa: F401  (installs Taichi's handlers, which stay chained behind)

    try:
        from _pytest.faulthandler import fault_handler_stderr_fd_key
        fd = request.config.stash[fault_handler_stderr_fd_key]
    except (ImportError, KeyError):
        return
    faulthandler.enable(file=fd, all_threads=True)


@pytest.fixture(autouse=True, scope="module")
def fresh_taichi_per_file():
    """Each test file starts with no Taichi program. A CI worker that had run a few hundred
    tests' scenes in one program (every solver's kernels compiled into it and kept) died
    without a signal in four of about eleven runs, each time in a test that runs a soft body's
    frame in debug mode; a fresh program per file bounds what one program holds. That this
    is why it died is not proven. A later crash (a segfault in JIT code in the first soft
    test of a file) fits a mechanism that is shown (test_package): Scenes of the previous
    file collected after the reset freed the new program's contact arrays at the same
    addresses; runtime.reset now keeps such arrays alive."""
    from taichi_dcd.core import runtime

    runtime.reset()


def rules_under_test():
    """The contact rules the tests run with: all of them, but those named in the environment
    variable TAICHI_DCD_RULES_OFF (rule[,rule...]): the way to see which tests guard a rule."""
    import os

    from taichi_dcd.contact.rules import ContactRules

    names = [n for n in os.environ.get("TAICHI_DCD_RULES_OFF", "").split(",") if n]
    return ContactRules.without(*names)


def pytest_configure(config):
    """Every solver built in this process without naming its rules uses rules_under_test()
    (tests that run the command line in a subprocess keep every rule on)."""
    from taichi_dcd.solver import fields

    rules = rules_under_test()
    if rules != fields.ContactRules():
        fields.ContactRules = lambda: rules


@pytest.fixture
def f64():
    taichi_dcd.init(arch="cpu", precision="f64", debug=True)


@pytest.fixture
def f64_scene():
    taichi_dcd.init(arch="cpu", precision="f64", debug=False)


@pytest.fixture(params=[pytest.param(False, id="fast"), pytest.param(True, id="debug", marks=pytest.mark.slow)])
def f64_then_debug(request):
    """For a whole-scene test worth bounds-checking: runs it without debug mode in the default
    suite and again in Taichi's debug mode (bounds checks) in the slow suite. A frame kernel
    compiles in ~12 s without debug mode and ~100 s with it. Yields whether debug is on."""
    taichi_dcd.init(arch="cpu", precision="f64", debug=request.param)
    return request.param


@pytest.fixture
def f32():
    taichi_dcd.init(arch="cpu", precision="f32", debug=True)


def random_pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n random triangle pairs with vertices uniform in the unit cube (~28% intersect)."""
    rng = np.random.default_rng(seed)
    return rng.random((n, 3, 3)), rng.random((n, 3, 3))


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random proper rotation matrix (3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


@pytest.fixture(scope="session")
def scene_run(tmp_path_factory):
    """run(name, scale=1.0, precision="f64", **changes) → metrics (dict) of a built-in scene
    run as `taichi-dcd run NAME --no-frames [--scale]` would, each at most
    once per session; `changes` set SimConfig fields. The metrics carry "out", the folder."""
    from taichi_dcd.scene.builtin import scene_config
    from taichi_dcd.scene.config import scale_scene
    from taichi_dcd.output.run import run_scene
    from taichi_dcd.scene.scene import Scene

    done = {}

    def run(name: str, scale: float = 1.0, precision: str = "f64", **changes) -> dict:
        key = (name, scale, precision, tuple(sorted(changes.items())))
        if key not in done:
            taichi_dcd.init(arch="cpu", precision=precision, debug=False)
            config = scale_scene(scene_config(name), scale) if scale != 1.0 else scene_config(name)
            for field, value in changes.items():
                setattr(config.sim, field, value)
            out = tmp_path_factory.mktemp(f"{name}-x{scale:g}-{precision}")
            metrics = run_scene(Scene(config), out, progress=None, notices=None)
            done[key] = dict(metrics, out=out)
        return done[key]

    return run
