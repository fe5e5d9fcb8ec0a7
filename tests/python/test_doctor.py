"""The dataset doctor against a known truth: synthetic sets of 200 episodes with each data fault
in its own known 10% (`chunkc synth --faults`, recorded in `faults.json`), over several seeds.
Recall and precision per fault kind must both reach 0.95, and a clean set flags nothing. The
truth comes from `faults.json`, written by the generator, never from the doctor.

`python tests/python/test_doctor.py` prints the table."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from conftest import run_chunkc  # noqa: E402

FAULTS = "frozen,clip,jump,lag:3,delta,scale:10,duplicate"
# faults.json kind -> the doctor's flag.
FLAG_OF = {
    "frozen": "frozen",
    "clip": "clipped",
    "jump": "jump",
    "lag": "misaligned",
    "delta": "mixed_convention",
    "scale": "units",
    "duplicate_episode": "duplicate",
}
DOCTOR_FLAGS = set(FLAG_OF.values()) | {"short"}
SEEDS = [0, 1, 2]


def synth_and_audit(tmp: Path, seed: int, faults=FAULTS, fmt="lerobot", episodes=200):
    out = tmp / f"s{seed}-{fmt}-{'clean' if not faults else 'faults'}"
    args = ["synth", out, "--format", fmt, "--episodes", episodes, "--steps", 150,
            "--action-dim", 6, "--state-dim", 6, "--fps", 10, "--seed", seed]
    if faults:
        args += ["--faults", faults, "--fault-fraction", 0.1]
    run_chunkc(*args)
    run_chunkc("audit", out / "spec.toml")
    audit = json.loads((out / "out" / "audit" / "audit.json").read_text())
    truth = {}
    if faults:
        for ep, injected in json.loads((out / "faults.json").read_text())["episodes"].items():
            for f in injected:
                truth.setdefault(FLAG_OF[f["fault"]], set()).add(int(ep))
    flagged = {}
    for e in audit["episodes"]:
        for f in e["flags"]:
            if f in DOCTOR_FLAGS:
                flagged.setdefault(f, set()).add(e["id"])
    return truth, flagged, audit


def scores(tmp: Path, seeds=SEEDS):
    table = {flag: [0, 0, 0] for flag in FLAG_OF.values()}  # tp, fn, fp
    for seed in seeds:
        truth, flagged, _ = synth_and_audit(tmp, seed)
        for flag in table:
            t, f = truth.get(flag, set()), flagged.get(flag, set())
            table[flag][0] += len(t & f)
            table[flag][1] += len(t - f)
            table[flag][2] += len(f - t)
    return table


def test_recall_and_precision_per_fault(tmp_path):
    table = scores(tmp_path)
    for flag, (tp, fn, fp) in table.items():
        recall = tp / max(tp + fn, 1)
        precision = tp / max(tp + fp, 1)
        assert tp + fn > 0, flag
        assert recall >= 0.95 and precision >= 0.95, (flag, tp, fn, fp)


def test_clean_sets_flag_nothing(tmp_path):
    for seed in SEEDS:
        _, flagged, audit = synth_and_audit(tmp_path, seed, faults=None)
        assert flagged == {}, flagged
        assert audit["doctor"]["lag_mode"] == 1
        assert audit["doctor"]["convention"] == "absolute"


def test_evidence_matches_the_injection(tmp_path):
    """The evidence numbers agree with what faults.json says was injected."""
    out = tmp_path / "e"
    truth, flagged, audit = synth_and_audit(tmp_path, 5)
    by_id = {e["id"]: e for e in audit["episodes"]}
    faults = json.loads((tmp_path / "s5-lerobot-faults" / "faults.json").read_text())["episodes"]
    for ep, injected in faults.items():
        f = injected[0]
        findings = {x["flag"]: x["evidence"] for x in by_id[int(ep)].get("findings", [])}
        if f["fault"] == "scale" and "units" in findings:
            assert np.isclose(findings["units"]["factor"], f["factor"], rtol=0.1)
        if f["fault"] == "lag" and "misaligned" in findings:
            assert findings["misaligned"]["lag"] - findings["misaligned"]["mode"] == -f["steps"]
        if f["fault"] == "duplicate_episode" and "duplicate" in findings:
            assert findings["duplicate"]["of"] == f["of"]
        if f["fault"] in ("frozen", "clip", "jump"):
            flag = FLAG_OF[f["fault"]]
            if flag in findings:
                assert findings[flag]["dim"] == f["dim"]


def test_exclude_and_error_verdicts(tmp_path):
    out = tmp_path / "v"
    run_chunkc("synth", out, "--format", "diffusion-policy-zarr", "--episodes", 60, "--steps", 120,
               "--action-dim", 4, "--state-dim", 4, "--fps", 10, "--faults", "scale:100",
               "--fault-fraction", 0.1)
    spec = out / "spec.toml"
    text = spec.read_text()
    spec.write_text(text + '\n[audit.doctor]\nunits = "exclude"\n')
    run_chunkc("audit", spec)
    audit = json.loads((out / "out" / "audit" / "audit.json").read_text())
    units = [e for e in audit["episodes"] if "units" in e["flags"]]
    assert len(units) == 6 and all(e["verdict"] == "exclude" for e in units)
    spec.write_text(text + '\n[audit.doctor]\nunits = "error"\n')
    proc = run_chunkc("audit", spec, check=False)
    assert proc.returncode != 0 and "units" in proc.stderr and "episode" in proc.stderr


if __name__ == "__main__":
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        table = scores(Path(d))
    print(f"{'fault':<18} {'flag':<17} {'TP':>4} {'FN':>4} {'FP':>4} {'recall':>7} {'precision':>9}")
    kinds = {v: k for k, v in FLAG_OF.items()}
    for flag, (tp, fn, fp) in table.items():
        print(f"{kinds[flag]:<18} {flag:<17} {tp:>4} {fn:>4} {fp:>4} {tp / max(tp + fn, 1):>7.3f} {tp / max(tp + fp, 1):>9.3f}")


def test_build_says_what_the_doctor_cost(tmp_path):
    """The doctor is on by default, so `build` prints its share of the wall time; with the doctor
    off it says nothing of it, and audit.json (deterministic) never holds a time."""
    run_chunkc("synth", tmp_path / "s", "--format", "aloha-hdf5", "--episodes", 6, "--steps", 60)
    spec = tmp_path / "s" / "spec.toml"
    proc = run_chunkc("build", "-q", spec)
    line = [l for l in proc.stderr.splitlines() if l.startswith("the dataset doctor took")]
    assert len(line) == 1, proc.stderr
    doctor, whole = (float(w) for w in line[0].split() if w.replace(".", "").isdigit())
    assert 0 <= doctor <= whole
    assert "the dataset doctor took" in run_chunkc("audit", spec).stderr
    audit = (tmp_path / "s" / "out" / "audit" / "audit.json").read_text()
    assert "seconds" not in audit
    spec.write_text(spec.read_text() + "\n[audit.doctor]\nenabled = false\n")
    proc = run_chunkc("build", "-q", spec)
    assert "doctor" not in proc.stderr, proc.stderr
