"""`chunkc analyze`: the ACF in analyze.json against numpy (always) and statsmodels (when
installed), averaged over episodes independently here; the suggested K and the profile checks
follow from those numbers; its HTML report is looked at in headless Chromium by test_report_browser.py."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from conftest import PUSHT, RawSource, make_replay_buffer, run_chunkc, write_spec

try:
    from statsmodels.tsa.stattools import acf as sm_acf
except ImportError:  # not in every environment; numpy's reference always runs
    sm_acf = None


def numpy_acf(x, nlags):
    """statsmodels' default ACF (adjusted=False, demean=True) via np.correlate; None if constant."""
    d = np.asarray(x, dtype=np.float64) - np.mean(x)
    denom = d @ d
    if len(x) < 2 or denom == 0:
        return None
    full = np.correlate(d, d, mode="full")[len(d) - 1 :]
    return full[: min(nlags, len(d) - 1) + 1] / denom


def mean_over_episodes(episodes, max_lag, acf_fn):
    """Per dimension: each lag averaged over the episodes that vary and are long enough."""
    width = episodes[0].shape[1]
    dims = []
    for d in range(width):
        sums, counts = np.zeros(max_lag + 1), np.zeros(max_lag + 1)
        for ep in episodes:
            r = acf_fn(ep[:, d].astype(np.float64), max_lag)
            if r is None:
                continue
            sums[: len(r)] += r
            counts[: len(r)] += 1
        dims.append(sums[counts > 0] / counts[counts > 0])
    longest = max(len(r) for r in dims)
    mean = np.array([np.mean([r[k] for r in dims if len(r) > k]) for k in range(longest)])
    return dims, mean


def statsmodels_acf(x, nlags):
    if np.ptp(x) == 0:
        return None
    return sm_acf(x, nlags=min(nlags, len(x) - 1), fft=True)


def run_analyze(spec, *args):
    proc = run_chunkc("analyze", spec, *args)
    report = json.loads((spec.parent / "out" / "audit" / "analyze.json").read_text())
    return proc, report


PROFILES = """
[profiles.dp]
preset = "diffusion_policy"
format = "hdf5"
[profiles.slow]
preset = "act"
fps = 5
chunk = 20
format = "hdf5"
"""


def check_against_reference(report, episodes, max_lag):
    refs = [("numpy", numpy_acf)] + ([("statsmodels", statsmodels_acf)] if sm_acf else [])
    for name, fn in refs:
        dims, mean = mean_over_episodes(episodes, max_lag, fn)
        assert len(report["dims"]) == len(dims)
        for got, want in zip(report["dims"], dims):
            np.testing.assert_allclose(got["acf"], want, rtol=0, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(report["mean_acf"], mean, rtol=0, atol=1e-9, err_msg=name)
    return mean


def test_pusht_acf_matches_numpy_and_statsmodels(tmp_path):
    spec = write_spec(tmp_path, PROFILES)
    proc, report = run_analyze(spec, "--max-lag", "60")
    raw = RawSource(PUSHT)
    episodes = [raw.episode("action", e) for e in range(len(raw.ends))]
    mean = check_against_reference(report, episodes, 60)
    assert report["max_lag"] == 60 and report["episodes"] == len(episodes)
    assert report["steps"] == sum(len(e) for e in episodes)
    assert report["episodes_at_lag"] == [sum(len(e) > k for e in episodes) for k in range(61)]

    below = np.flatnonzero(mean[1:] < 0.3)
    assert below.size > 0, "Push-T's ACF drops below 0.3 well within 60 steps"
    k = int(below[0]) + 1
    assert report["suggested_k"] == k
    assert f"suggested K: {k} steps at 10 Hz" in proc.stdout

    by_name = {p["name"]: p for p in report["profiles"]}
    # dp: K = 16 at the source rate; slow: K = 20 at 5 Hz = 40 source steps.
    for name, factor, chunk in [("dp", 1, 16), ("slow", 2, 20)]:
        p = by_name[name]
        assert p["rate_factor"] == factor and p["chunk_source_steps"] == chunk * factor
        assert p["acf_at_chunk"] == pytest.approx(mean[chunk * factor], abs=1e-9)
        assert p["suggested_chunk"] == -(-k // factor)
        r = mean[chunk * factor]
        if r > 0.5:
            assert p["warning"].startswith("redundant")
        elif r < 0.1:
            assert p["warning"].startswith("long chunk")
        else:
            assert p["warning"] is None


def test_short_episodes_and_constant_dimensions(tmp_path):
    rng = np.random.default_rng(3)

    def walk(n):
        return np.cumsum(rng.normal(size=(n, 3)), axis=0).astype(np.float32)

    episodes = [walk(50), walk(6), walk(30)]
    episodes[1][:, 2] = 1.5  # dimension 2 is constant in the second episode
    episodes[2][:, 0] = -2.0  # dimension 0 is constant in the third
    source = make_replay_buffer(tmp_path / "walk.zarr", [{"action": e} for e in episodes])
    spec = write_spec(tmp_path, '[profiles.p]\nchunk = 8\nformat = "hdf5"', source=source,
                      channels={"action": "action"})
    proc, report = run_analyze(spec)  # default max lag: capped at the longest episode - 1
    assert report["max_lag"] == 49
    check_against_reference(report, episodes, 49)
    assert report["episodes_at_lag"] == [sum(len(e) > k for e in episodes) for k in range(50)]
    assert [d["constant_episodes"] for d in report["dims"]] == [[2], [], [1]]
    assert "constant in 1 episode(s)" in proc.stdout


def test_analyze_output_is_deterministic_and_bad_channels_are_refused(tmp_path):
    spec = write_spec(tmp_path, PROFILES)
    run_chunkc("analyze", spec)
    audit = tmp_path / "out" / "audit"
    first = [(audit / f).read_bytes() for f in ("analyze.json", "analyze.html")]
    run_chunkc("-j", "1", "analyze", spec)
    assert first == [(audit / f).read_bytes() for f in ("analyze.json", "analyze.html")]

    unknown = run_chunkc("analyze", spec, "--channel", "observation.nope", check=False)
    assert unknown.returncode == 2 and "observation.nope" in unknown.stderr
    image = run_chunkc("analyze", spec, "--channel", "observation.image", check=False)
    assert image.returncode == 2 and "holds images" in image.stderr



def test_analyze_never_writes_into_the_source(tmp_path):
    source = make_replay_buffer(tmp_path / "src.zarr", [{"action": np.arange(20, dtype=np.float32)[:, None]}])
    spec = write_spec(tmp_path, '[profiles.p]\nchunk = 4', source=source, channels={"action": "action"})
    spec.write_text(spec.read_text().replace('dir = "out"', 'dir = "src.zarr/out"'))
    proc = run_chunkc("analyze", spec, check=False)
    assert proc.returncode == 2 and "inside the source" in proc.stderr
    assert not (source / "out").exists()


FULL = os.environ.get("CHUNKC_FULL_PUSHT")


@pytest.mark.skipif(not FULL, reason="set CHUNKC_FULL_PUSHT to the full Push-T zarr")
def test_full_pusht_acf(tmp_path):
    spec = write_spec(tmp_path, PROFILES, source=Path(FULL))
    proc, report = run_analyze(spec)
    raw = RawSource(Path(FULL))
    episodes = [raw.episode("action", e) for e in range(len(raw.ends))]
    assert report["max_lag"] == 200 and report["episodes"] == 206
    mean = check_against_reference(report, episodes, 200)
    k = int(np.flatnonzero(mean[1:] < 0.3)[0]) + 1
    assert report["suggested_k"] == k and f"suggested K: {k} steps" in proc.stdout
