"""The dataset doctor stays quiet on clean real data (issue 37): `chunkc audit` of every vendored
real source (Bridge's RLDS subset, the Unitree G1 LeRobot subset, Push-T, robosuite Panda and
Sawyer, ALOHA's simulated demos) flags at most 5% of the episodes with each signal check. Before
the checks were measured against each dimension's own motion and range, the G1 set, short Bridge
episodes and robosuite's teleoperated deltas flagged most of theirs (`jump` 34 of 50 on Bridge).
The larger real sets are in `bench/doctor_real.py` (book: doctor.md, "Calibrated on real data")."""

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from conftest import REPO, run_chunkc  # noqa: E402

SPECS = ["bridge", "lerobot_g1", "pusht", "robosuite_panda", "robosuite_sawyer", "aloha_sim"]
SIGNAL = ["frozen", "clipped", "jump", "units", "misaligned", "mixed_convention"]


@pytest.mark.parametrize("name", SPECS)
def test_clean_real_data_flags_few_episodes(tmp_path, name):
    text = (REPO / "specs" / f"{name}.toml").read_text()
    # The spec's paths are relative to specs/; write the outputs under tmp_path.
    spec = tmp_path / f"{name}.toml"
    lines = []
    for line in text.splitlines():
        if line.startswith("path = "):
            rel = line.split("=", 1)[1].split("#")[0].strip().strip('"')
            line = f'path = "{(REPO / "specs" / rel).resolve()}"'
        elif line.startswith("dir = "):
            line = f'dir = "{tmp_path / "out"}"'
        lines.append(line)
    spec.write_text("\n".join(lines) + "\n")
    run_chunkc("audit", spec)
    audit = json.loads((tmp_path / "out" / "audit" / "audit.json").read_text())
    n = len(audit["episodes"])
    for flag in SIGNAL:
        hit = [e["id"] for e in audit["episodes"] if flag in e["flags"]]
        assert len(hit) <= 0.05 * n, (name, flag, hit)


def test_bridge_duplicates_are_exact_copies(tmp_path):
    """Bridge's debug subset stores its 25 validation episodes again as copies of training ones:
    the doctor's `duplicate` findings name them, each at RMS difference 0."""
    spec = tmp_path / "bridge.toml"
    test_clean_real_data_flags_few_episodes(tmp_path, "bridge")
    audit = json.loads((tmp_path / "out" / "audit" / "audit.json").read_text())
    dups = [f["evidence"] for e in audit["episodes"] for f in e.get("findings", [])
            if f["flag"] == "duplicate"]
    assert len(dups) == 25 and all(d["rms"] == 0.0 for d in dups), dups
    assert spec.exists()
