"""The doctor's `jump` and `units` checks on a realistic set made by a generator of our own
(`tracking_set.py`, independent of `chunkc synth`'s fault injection): the state tracks the
commanded action, `state[t+1] = state[t] + a (cmd[t] - state[t]) + noise`; a tenth of the
episodes get three single-step spikes of 10-30% of a dimension's range in one
action dimension, another tenth are recorded in degrees where the rest are radians (action and
state both scaled). Over several seeds, each of the two flags must reach precision and recall of
0.95 against the generator's truth file, no other doctor check may fire on these sets, and the
clean sets of the same seeds must flag nothing.

`python tests/python/test_doctor_tracking.py` prints the per-kind table."""

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tracking_set  # noqa: E402
from conftest import run_chunkc  # noqa: E402
from test_doctor import DOCTOR_FLAGS  # noqa: E402

SEEDS = [0, 1, 2]
FLAG_OF = {"spike": "jump", "units": "units"}


def audit(tmp: Path, seed: int, faults=tracking_set.KINDS):
    root = tmp / f"tracking-{seed}-{'faults' if faults else 'clean'}"
    truth = tracking_set.write(root, episodes=200, seed=seed, faults=faults)
    spec = tmp / f"{root.name}.toml"
    spec.write_text("\n".join([
        "version = 1", "[source]", 'format = "lerobot"', f'path = "{root}"',
        "[source.channels]", 'action = "action"', '"observation.state" = "observation.state"',
        "[output]", f'dir = "{root}-out"', "[profiles.act]", 'preset = "act"', "fps = 10",
        "chunk = 10", ""]))
    run_chunkc("audit", spec)
    report = json.loads((tmp / f"{root.name}-out" / "audit" / "audit.json").read_text())
    flagged = {}
    for e in report["episodes"]:
        for f in e["flags"]:
            if f in DOCTOR_FLAGS:
                flagged.setdefault(f, set()).add(e["id"])
    want = {}
    for e, injected in truth.items():
        for f in injected:
            want.setdefault(FLAG_OF[f["kind"]], set()).add(int(e))
    return want, flagged


def table(tmp: Path, seeds=SEEDS):
    """Per doctor flag: (true positives, missed, false positives), summed over the seeds."""
    out = {flag: [0, 0, 0] for flag in sorted(DOCTOR_FLAGS)}
    for seed in seeds:
        want, flagged = audit(tmp, seed)
        for flag, row in out.items():
            t, f = want.get(flag, set()), flagged.get(flag, set())
            row[0] += len(t & f)
            row[1] += len(t - f)
            row[2] += len(f - t)
    return out


def test_jump_and_units_catch_the_planted_faults(tmp_path):
    rows = table(tmp_path)
    for flag in ("jump", "units"):
        tp, fn, fp = rows[flag]
        assert tp + fn == 20 * len(SEEDS), (flag, rows[flag])
        assert tp / (tp + fp) >= 0.95 and tp / (tp + fn) >= 0.95, (flag, rows[flag])
    # No other check mistakes these faults (or the motion) for its own.
    others = {f: r for f, r in rows.items() if f not in FLAG_OF.values() and r[2]}
    assert not others, others


@pytest.mark.parametrize("seed", SEEDS[:2])
def test_the_clean_tracking_set_flags_nothing(tmp_path, seed):
    _, flagged = audit(tmp_path, seed, faults=())
    assert not flagged, {f: sorted(e)[:10] for f, e in flagged.items()}


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        rows = table(Path(d))
    print("flag              TP   FN   FP  recall precision")
    for flag, (tp, fn, fp) in rows.items():
        rec = tp / (tp + fn) if tp + fn else float("nan")
        prec = tp / (tp + fp) if tp + fp else float("nan")
        print(f"{flag:16s} {tp:4d} {fn:4d} {fp:4d}  {rec:6.3f}   {prec:6.3f}")
