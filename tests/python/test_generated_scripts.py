"""The generated validate.py and smoke_train.py run, and show what they claim to show."""

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import model_tier, run_chunkc, write_spec

PROFILES = """
[profiles.dp]
preset = "diffusion_policy"
"""


@pytest.fixture(scope="module")
def lowdim(tmp_path_factory):
    d = tmp_path_factory.mktemp("scripts")
    spec = write_spec(d, PROFILES, channels={"action": "action", "observation.state": "state"})
    run_chunkc("build", "-q", spec)
    return d / "out" / "dp"


def test_validate_writes_plots_and_runs_a_forward_pass(tmp_path, lowdim):
    model_tier("torch")  # validate.py runs the target policy forward
    out = tmp_path / "validate"
    proc = subprocess.run(
        [sys.executable, str(lowdim / "validate.py"), "--out", str(out)], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    # LeRobot's Diffusion Policy conditions on an image or an environment state: a state-only
    # profile gets the MLP, labelled as not the target model.
    assert "forward pass of MLP stand-in, not the target model" in proc.stdout
    assert "action " in proc.stdout and "(8, 16, 2)" in proc.stdout
    report = json.loads((out / "validate.json").read_text())
    # Three episode plots and the histograms of the normalized action and state.
    assert len(report["files"]) == 5 and {"hist_action.png", "hist_observation.state.png"} <= set(report["files"])
    for name in report["files"]:
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 2000


def test_validate_animates_image_channels(tmp_path):
    model_tier("torch")  # validate.py runs the target policy forward
    spec = write_spec(tmp_path, PROFILES)
    run_chunkc("build", "-q", spec)
    out = tmp_path / "v"
    proc = subprocess.run(
        [sys.executable, str(tmp_path / "out" / "dp" / "validate.py"), "--out", str(out), "--episodes", "1"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    gifs = list(out.glob("*.gif"))
    assert len(gifs) == 1 and gifs[0].read_bytes()[:6] in (b"GIF89a", b"GIF87a")


def test_smoke_training_learns_and_error_grows_with_horizon(tmp_path, lowdim):
    model_tier("torch")
    out = tmp_path / "smoke"
    proc = subprocess.run(
        [sys.executable, str(lowdim / "smoke_train.py"), "--out", str(out), "--epochs", "25", "--batch-size", "128"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    m = json.loads((out / "metrics.json").read_text())
    assert m["final_loss"] < 0.5 * m["initial_loss"], m["losses"]
    err = np.asarray(m["per_step_error"])
    assert len(err) == 16
    # Later steps of the chunk are harder to predict: the error rises with the horizon.
    assert err[-4:].mean() > err[:4].mean()
    assert np.corrcoef(np.arange(16), err)[0, 1] > 0.5
    for png in ("loss.png", "horizon_error.png"):
        assert (out / png).read_bytes()[:4] == b"\x89PNG"
