"""The temporal audit and its repairs, checked against independent numpy / scipy computations.

- A synthetic robosuite-style source (timestamps in `states[:, 0]`) with known faults gets
  exactly the expected verdicts, and the built dataset holds what scipy computes:
  `CubicSpline` (not-a-knot) for re-gridded episodes, `signal.resample` for the one recorded at
  8 Hz instead of 10, the nearest frame for images.
- On the real robosuite files (Sawyer: 0.010 / 0.012 s steps; Baxter: repeated timestamps) the
  flags and interval statistics are what numpy computes from `states[:, 0]` with the documented
  rules.
- A profile rate that does not divide the source's is resampled as `signal.resample` (and
  `numpy.interp` with `[audit] resample = "linear"`).
"""

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy import signal
from scipy.interpolate import CubicSpline

from conftest import PUSHT, REPO, RawSource, run_chunkc, write_spec

FPS = 10.0
T = 1.0 / FPS


def _values(t, seed):
    """Smooth state (3 columns) and action (2 columns) signals of time."""
    rng = np.random.default_rng(seed)
    f, p = rng.uniform(0.2, 0.6, 5), rng.uniform(0, 6, 5)
    cols = [np.sin(2 * np.pi * f[i] * t + p[i]) + 0.1 * i * t for i in range(5)]
    return np.stack(cols[:3], 1), np.stack(cols[3:], 1)


def _faulty_timestamps():
    rng = np.random.default_rng(7)
    clean = np.arange(40) * T
    dropped = np.delete(np.arange(52) * T, [10, 30])  # 2 dropped frames
    slow = np.arange(40) * 0.125  # 8 Hz instead of 10
    jitter = np.concatenate([[0.0], np.cumsum(T * (1 + rng.uniform(-0.3, 0.3, 49)))])
    repeats = np.insert(np.arange(30) * T, 12, 12 * T)  # one repeated timestamp
    return {1: clean, 2: dropped, 3: slow, 4: jitter, 5: repeats}


EXPECTED = {1: "ok", 2: "interpolate", 3: "resample", 4: "interpolate", 5: "interpolate"}


def write_faulty_source(path: Path):
    """robosuite 0.3's layout: data/demo_<i>/{states, actions, <image>}, time in states[:, 0]."""
    with h5py.File(path, "w") as f:
        data = f.create_group("data")
        for i, t in _faulty_timestamps().items():
            state, action = _values(t, i)
            g = data.create_group(f"demo_{i}")
            g["states"] = np.concatenate([t[:, None], state], 1)
            g["actions"] = action
            # Frame k is filled with the value k: the nearest-frame choice is readable.
            frames = np.broadcast_to(np.arange(len(t), dtype=np.uint8)[:, None, None, None], (len(t), 4, 6, 3))
            g["agentview_image"] = np.ascontiguousarray(frames)


def write_audit_spec(directory: Path, source: Path, audit: str = "", profiles: str = None) -> Path:
    profiles = profiles or '[profiles.rm]\nformat = "robomimic_hdf5"\nchunk = 4\n'
    spec = directory / "spec.toml"
    spec.write_text(
        f"""version = 1
[source]
format = "robomimic_hdf5"
path = "{source}"
fps = {FPS}
[source.channels]
action = "actions"
"observation.state" = {{ key = "states", columns = [1, 4] }}
"observation.image" = "agentview_image"
[split]
val_fraction = 0.2
seed = 0
{audit}
[output]
dir = "out"
{profiles}"""
    )
    return spec


def kept_times(t):
    """Repeated timestamps dropped, the first of each run kept (numpy)."""
    keep = np.concatenate([[True], np.diff(t) != 0])
    return t[keep], np.flatnonzero(keep)


@pytest.fixture(scope="module")
def faulty(tmp_path_factory):
    d = tmp_path_factory.mktemp("audit")
    src = d / "faulty.hdf5"
    write_faulty_source(src)
    spec = write_audit_spec(d, src)
    audit_run = run_chunkc("audit", spec)
    run_chunkc("build", spec, "--quiet")
    report = json.loads((d / "out/audit/audit.json").read_text())
    return d, src, report, audit_run.stdout


def test_verdicts_and_flags(faulty):
    _, _, report, stdout = faulty
    assert report["expected_interval"] == pytest.approx(T)
    got = {e["id"]: e["verdict"] for e in report["episodes"]}
    assert got == EXPECTED
    flags = {e["id"]: set(e["flags"]) for e in report["episodes"]}
    assert flags[1] == set()
    assert "gap" in flags[2]
    assert flags[3] == {"count"}
    assert "jitter" in flags[4]
    assert "non_monotonic" in flags[5]
    assert report["repaired_fraction"] == pytest.approx(4 / 5)
    assert any("fix the recording setup" in w for w in report["warnings"])
    assert "interpolate 3" in stdout and "resample 1" in stdout

    # Interval statistics as numpy computes them.
    for e in report["episodes"]:
        dt = np.diff(_faulty_timestamps()[e["id"]])
        assert e["n_frames"] == len(dt) + 1
        for key, want in [("mean", dt.mean()), ("std", dt.std()), ("min", dt.min()), ("max", dt.max())]:
            assert e[f"interval_{key}"] == pytest.approx(want, abs=1e-12), (e["id"], key)


def test_audit_json_is_deterministic(faulty):
    d, _, _, _ = faulty
    first = (d / "out/audit/audit.json").read_bytes()
    run_chunkc("-j", "1", "audit", d / "spec.toml")
    assert (d / "out/audit/audit.json").read_bytes() == first
    assert not list((d / "out/audit").glob(".*tmp"))


def test_repairs_match_scipy(faulty):
    d, src, report, _ = faulty
    meta = json.loads((d / "out/rm/meta.json").read_text())
    ids = meta["episodes"]
    assert {r["id"] for r in meta["repaired"]} == {2, 3, 4, 5}
    by_id = {e["id"]: e for e in report["episodes"]}
    with h5py.File(src, "r") as s, h5py.File(d / "out/rm/data.hdf5", "r") as out:
        for i, eid in enumerate(ids):
            g = s[f"data/demo_{eid}"]
            t = g["states"][:, 0]
            # chunkc reads values as float32.
            state = g["states"][:, 1:4].astype(np.float32).astype(np.float64)
            action = g["actions"][:].astype(np.float32).astype(np.float64)
            o = out[f"data/demo_{i}"]
            got_state, got_action = o["obs/state"][:], o["actions"][:]
            got_image = o["obs/agentview_image"][:, 0, 0, 0]  # the source key
            verdict = by_id[eid]["verdict"]
            if verdict == "ok":
                want_state, want_action = state, action
                want_image = np.arange(len(t))
            elif verdict == "interpolate":
                tk, keep = kept_times(t)
                steps = int(np.floor((tk[-1] - tk[0]) / T + 1e-6)) + 1
                grid = tk[0] + np.arange(steps) * T
                want_state = CubicSpline(tk, state[keep])(grid)
                want_action = CubicSpline(tk, action[keep])(grid)
                nearest = np.abs(grid[:, None] - tk[None, :])
                # Ties go to the earlier frame: argmin returns the first minimum.
                want_image = keep[np.argmin(nearest, axis=1)]
            else:
                steps = int(round(len(t) * np.diff(t).mean() / T))
                assert steps == 50
                want_state = signal.resample(state, steps, axis=0)
                want_action = signal.resample(action, steps, axis=0)
                p = np.arange(steps) * len(t) / steps
                want_image = np.minimum(np.where(p - np.floor(p) > 0.5, np.ceil(p), np.floor(p)), len(t) - 1)
            assert by_id[eid]["repaired_frames"] == len(want_state)
            np.testing.assert_allclose(got_state, want_state, rtol=0, atol=1e-6, err_msg=f"episode {eid}")
            np.testing.assert_allclose(got_action, want_action, rtol=0, atol=1e-6, err_msg=f"episode {eid}")
            np.testing.assert_array_equal(got_image, want_image.astype(np.uint8), err_msg=f"episode {eid}")


def test_examples_are_regular_after_repair(faulty):
    _, _, report, _ = faulty
    examples = report["examples"]
    assert 1 <= len(examples) <= 3
    for ex in examples:
        assert ex["channel"] == "observation.state"
        np.testing.assert_allclose(np.diff(ex["after_t"]), T, rtol=0, atol=1e-9)
        t = _faulty_timestamps()[ex["episode"]]
        np.testing.assert_allclose(ex["before_t"], t)


def test_policies_exclude_and_error(tmp_path):
    src = tmp_path / "faulty.hdf5"
    write_faulty_source(src)
    spec = write_audit_spec(
        tmp_path, src, '[audit]\nrate_error = "exclude"\nirregular = "exclude"\nnon_monotonic = "exclude"\nmax_dropped = 1'
    )
    run_chunkc("audit", spec)
    report = json.loads((tmp_path / "out/audit/audit.json").read_text())
    assert {e["id"]: e["verdict"] for e in report["episodes"]} == {
        1: "ok", 2: "exclude", 3: "exclude", 4: "exclude", 5: "exclude"}
    run_chunkc("build", spec, "--quiet")
    meta = json.loads((tmp_path / "out/rm/meta.json").read_text())
    assert meta["episodes"] == [1]
    assert sorted(e["id"] for e in meta["excluded"]) == [2, 3, 4, 5]

    spec = write_audit_spec(tmp_path, src, '[audit]\nnon_monotonic = "error"')
    proc = run_chunkc("audit", spec, check=False)
    assert proc.returncode != 0
    assert "episode 5" in proc.stderr and "step 13" in proc.stderr and "non_monotonic" in proc.stderr


def numpy_flags(t, fps, jitter=0.1, gap=2.0, count=0.05):
    """The documented flag rules, in numpy."""
    dt = np.diff(t)
    flags = set()
    if dt.std() > jitter * dt.mean():
        flags.add("jitter")
    if dt.max() > gap / fps:
        flags.add("gap")
    frames = (t[-1] - t[0]) * fps + 1
    if abs(len(t) - frames) > count * frames:
        flags.add("count")
    if (dt <= 0).any():
        flags.add("non_monotonic")
    return flags


def numpy_bimodal(dts, expected, separation=0.1, share=0.05):
    s = np.sort(dts)
    breaks = np.flatnonzero(np.diff(s) > separation * expected) + 1
    sizes = np.diff(np.concatenate([[0], breaks, [len(s)]]))
    return int((sizes >= share * len(s)).sum()) >= 2


@pytest.mark.parametrize("name", ["robosuite_sawyer_lift", "robosuite_baxter_peg_in_hole"])
def test_robosuite_flags_match_numpy(tmp_path, name):
    src = REPO / "tests/data" / f"{name}.hdf5"
    spec = tmp_path / "spec.toml"
    spec.write_text(
        f"""version = 1
[source]
format = "robomimic_hdf5"
path = "{src}"
fps = 100
[source.channels]
action = {{ key = "states", columns = [1, 4] }}
[output]
dir = "out"
[profiles.p]
chunk = 8
"""
    )
    proc = run_chunkc("audit", spec)
    report = json.loads((tmp_path / "out/audit/audit.json").read_text())
    all_dt = []
    with h5py.File(src, "r") as f:
        names = sorted(f["data"].keys(), key=lambda k: int(k.split("_")[1]))
        assert [e["id"] for e in report["episodes"]] == [int(k.split("_")[1]) for k in names]
        for e, k in zip(report["episodes"], names):
            t = f[f"data/{k}/states"][:, 0]
            dt = np.diff(t)
            all_dt.append(dt)
            assert set(e["flags"]) == numpy_flags(t, 100.0), k
            assert e["interval_mean"] == pytest.approx(dt.mean(), abs=1e-12)
            assert e["interval_std"] == pytest.approx(dt.std(), abs=1e-12)
            assert e["interval_min"] == pytest.approx(dt.min(), abs=1e-12)
            assert e["interval_max"] == pytest.approx(dt.max(), abs=1e-12)
            # Irregular 0.010 / 0.012 s steps without holes: re-gridded onto 0.01 s steps.
            assert e["verdict"] == "interpolate"
            tk, _ = kept_times(t)
            assert e["repaired_frames"] == int(np.floor((tk[-1] - tk[0]) / 0.01 + 1e-6)) + 1
    all_dt = np.concatenate(all_dt)
    assert numpy_bimodal(all_dt, 0.01)
    assert any("bimodal" in w for w in report["warnings"])
    assert sum(report["histogram"]["counts"]) == len(all_dt)
    assert "bimodal" in proc.stdout


@pytest.mark.parametrize("method", ["fourier", "linear"])
def test_non_integer_rate_matches_scipy(tmp_path, method):
    # Push-T at 10 Hz to a 4 Hz profile: ratio 2.5, each episode resampled to round(n * 0.4).
    spec = write_spec(
        tmp_path,
        '[profiles.rm]\nfps = 4\nchunk = 2\nformat = "robomimic_hdf5"\n',
        channels={"action": "action", "observation.state": "state"},
    )
    spec.write_text(spec.read_text().replace("[output]", f'[audit]\nresample = "{method}"\n[output]'))
    run_chunkc("build", spec, "--quiet")
    raw = RawSource(PUSHT)
    meta = json.loads((tmp_path / "out/rm/meta.json").read_text())
    assert meta["rate"]["factor"] is None
    with h5py.File(tmp_path / "out/rm/data.hdf5", "r") as out:
        for i, e in enumerate(meta["episodes"]):
            for key, name in [("action", "actions"), ("state", "obs/state")]:
                x = raw.episode(key, e).astype(np.float32).astype(np.float64)
                n = len(x)
                num = int(round(n * 4 / 10))
                if method == "fourier":
                    want = signal.resample(x, num, axis=0)
                else:
                    p = np.arange(num) * n / num
                    want = np.stack([np.interp(p, np.arange(n), x[:, c]) for c in range(x.shape[1])], 1)
                got = out[f"data/demo_{i}/{name}"][:]
                # Push-T positions reach ~500: float32 storage limits the absolute precision.
                np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * max(1.0, np.abs(want).max()))
