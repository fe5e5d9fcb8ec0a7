"""Shared helpers: the chunkc binary, spec writing, and an independent reading of the source."""

import atexit
import functools
import os
import shutil
import sys
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
import zarr

REPO = Path(__file__).resolve().parents[2]
PUSHT = REPO / "tests" / "data" / "pusht_subset.zarr"
G1 = REPO / "tests" / "data" / "lerobot_g1_subset"


def model_tier(module: str):
    """`module` from the Python model tier (torch, LeRobot, gym-pusht), or a skip that says why it
    is missing: scripts/setup.sh installs that tier only where the disk has room for it."""
    return pytest.importorskip(module, reason=f"{module} is not installed: {tier_line()}")


# LeRobot's video backends, its default first. `LeRobotDataset(video_backend=None)` takes
# torchcodec whenever it is installed (lerobot.datasets.video_utils.get_safe_default_codec), and
# torchcodec loads the system FFmpeg: a test that only tried pyav would pass on a machine where
# every user with LeRobot's defaults fails to read a frame.
VIDEO_BACKENDS = [pytest.param(None, id="default-torchcodec"), pytest.param("pyav", id="pyav")]


def lerobot_dataset(repo_id: str, root, backend=None):
    """`LeRobotDataset` over a local set with the video backend `backend` (None: LeRobot's
    default, which must then be torchcodec, the model tier installs it)."""
    LeRobotDataset = model_tier("lerobot.datasets.lerobot_dataset").LeRobotDataset
    ds = LeRobotDataset(repo_id, root=root, video_backend=backend)
    if backend is None:
        assert ds.video_backend == "torchcodec", f"LeRobot's default backend is {ds.video_backend}"
    return ds


def tier_line() -> str:
    """What scripts/setup.sh installed into the venv, and why (its .chunkc-tier file)."""
    marker = Path(sys.prefix) / ".chunkc-tier"
    if not marker.exists():
        return "this interpreter was not set up by scripts/setup.sh"
    tier, _, reason = marker.read_text().partition("\n")
    return f"Python tier '{tier}' ({reason.strip()})"


def pytest_report_header(config):
    return tier_line()


def chunkc_bin() -> str:
    path = os.environ.get("CHUNKC_BIN", str(REPO / "target" / "release" / "chunkc"))
    if not Path(path).exists():
        pytest.fail(f"chunkc binary not found at {path}; run `cargo build --release` first")
    return path


def run_chunkc(*args, env=None, check=True):
    full_env = dict(os.environ)
    full_env.update(env or {})
    proc = subprocess.run([chunkc_bin(), *map(str, args)], capture_output=True, text=True, env=full_env)
    if check and proc.returncode != 0:
        raise AssertionError(f"chunkc {' '.join(map(str, args))} failed ({proc.returncode}):\n{proc.stderr}")
    return proc


def build_with_video(path, *args):
    """`chunkc build -q ARGS PATH`, which must succeed; a binary without the `video` feature
    fails the test with what to do (these tests are not skipped: CI builds with it)."""
    proc = run_chunkc("build", "-q", *args, path, check=False)
    if "without the `video` feature" in proc.stderr:
        pytest.fail("the chunkc binary lacks the `video` feature: cargo build --release --features video")
    assert proc.returncode == 0, proc.stderr
    return proc


def write_spec(directory: Path, profiles: str, source: Path = PUSHT, fps: float = 10,
               channels=None, split="val_fraction = 0.1\nseed = 0") -> Path:
    """A spec in `directory` reading `source`, with the given `[profiles.*]` TOML text."""
    channels = channels or {"action": "action", "observation.state": "state", "observation.image": "img"}
    lines = [
        "version = 1",
        "[source]",
        'format = "diffusion_policy_zarr"',
        f'path = "{source}"',
        f"fps = {fps}",
        "[source.channels]",
        *[f'"{k}" = "{v}"' for k, v in channels.items()],
        "[split]",
        split,
        "[output]",
        'dir = "out"',
        profiles,
    ]
    spec = directory / "spec.toml"
    spec.write_text("\n".join(lines) + "\n")
    return spec


MIXTURE_PROFILES = """
[profiles.dp]
preset = "diffusion_policy"
fps = 10
format = "zarr"

[profiles.act]
preset = "act"
fps = 10
chunk = 8

[profiles.lerobot]
preset = "diffusion_policy"
fps = 10
format = "parquet"
"""


def write_mixture_spec(directory: Path, mixture='pad_to = { action = 32, "observation.state" = 32 }',
                 own_extra="weight = 0.7", sim_extra="weight = 0.3", profiles=MIXTURE_PROFILES,
                 split="val_fraction = 0.25\nseed = 0", sim: Path = PUSHT) -> Path:
    """A training mixture in `directory`: the G1 humanoid subset (30 Hz, 26-wide action and
    state) as `own` and Push-T (10 Hz, 2 and 5) as `sim`, with `[mixture]` `mixture`."""
    text = f"""version = 1

[sources.own]
format = "lerobot"
path = "{G1}"
{own_extra}
[sources.own.channels]
action = "action"
"observation.state" = "observation.state"

[sources.sim]
format = "diffusion_policy_zarr"
path = "{sim}"
fps = 10
{sim_extra}
[sources.sim.channels]
action = "action"
"observation.state" = "state"

[mixture]
{mixture}

[split]
{split}

[output]
dir = "out"
{profiles}
"""
    spec = directory / "spec.toml"
    spec.write_text(text)
    return spec



# The scripts chunkc generates per profile, from the parts the profile reads (src/render/parts.rs).
PROFILE_SCRIPTS = ("loader.py", "validate.py")


def every_part_templates(directory: Path) -> Path:
    """`directory/tpl`, a template override directory (`[output] templates = "tpl"`) that renders
    this checkout's loader.py and validate.py with every part (`{% set parts = every %}` before
    templates/<script>.j2, and the parts of templates/<script stem>/): scripts that read any
    profile, so that a test can give a built profile's meta.json what its build had not (a
    mixture, transforms)."""
    tpl = directory / "tpl"
    tpl.mkdir()
    for script in PROFILE_SCRIPTS:
        entry = (REPO / "templates" / f"{script}.j2").read_text()
        (tpl / f"{script}.j2").write_text("{% set parts = every %}\n" + entry)
        stem = script.removesuffix(".py")
        shutil.copytree(REPO / "templates" / stem, tpl / stem)
    return tpl


@functools.lru_cache(maxsize=None)
def every_part_scripts() -> dict:
    """{script: text} of loader.py and validate.py with every part (`every_part_templates`), as
    the chunkc binary renders them: from a small Push-T build, once per test process."""
    d = Path(tempfile.mkdtemp(prefix="chunkc_every_part_"))
    atexit.register(shutil.rmtree, d, True)
    every_part_templates(d)
    spec = write_spec(d, 'templates = "tpl"\n[profiles.p]\nchunk = 4\n',
                      channels={"action": "action", "observation.state": "state"})
    run_chunkc("build", "-q", spec)
    return {script: (d / "out" / "p" / script).read_text() for script in PROFILE_SCRIPTS}


class RawSource:
    """The source read with zarr-python: per-episode raw arrays, independent of chunkc."""

    def __init__(self, path: Path = PUSHT):
        root = zarr.open(str(path), mode="r")
        self.ends = root["meta/episode_ends"][:].astype(np.int64)
        self.starts = np.concatenate([[0], self.ends[:-1]])
        self.root = root
        self._cache = {}

    def array(self, key):
        if key not in self._cache:
            self._cache[key] = self.root["data"][key][:]
        return self._cache[key]

    def episode(self, key, e, factor=1):
        return self.array(key)[self.starts[e] : self.ends[e]][::factor]


@pytest.fixture(scope="session")
def raw():
    return RawSource()


def make_replay_buffer(path: Path, episodes):
    """A Diffusion Policy zarr replay buffer from a list of {key: (T, ...) array} episodes."""
    root = zarr.open_group(str(path), mode="w")
    lengths = [len(next(iter(e.values()))) for e in episodes]
    root.create_group("meta").array("episode_ends", np.cumsum(lengths).astype(np.int64))
    data = root.create_group("data")
    for key in episodes[0]:
        data.array(key, np.concatenate([e[key] for e in episodes]), chunks=(64,) + episodes[0][key].shape[1:])
    return path


def import_loader(root):
    """The generated `loader` module of the profile directory `root`, freshly imported."""
    import importlib

    sys.path.insert(0, str(root))
    try:
        import loader

        return importlib.reload(loader)
    finally:
        sys.path.pop(0)


def loader_module(root):
    """The generated `loader` module of the profile directory `root`, imported under a name of its
    own: each profile's loader holds the parts of its own profile, and several live side by side
    in one test."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"loader_of_{root.parent.name}_{root.name}", root / "loader.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load_dataset(root, split="train"):
    """`ChunkedDataset(root, split)` from the profile's own generated loader, imported under a
    name of its own (several profiles' loaders live side by side in one test)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"loader_{root.name}_{split}", root / "loader.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.ChunkedDataset(str(root), split)


def bits(x):
    """float32 arrays as their bit patterns, for bit-for-bit comparisons (NaN == NaN)."""
    x = np.asarray(x)
    return x.view(np.uint32) if x.dtype == np.float32 else x
