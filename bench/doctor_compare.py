"""chunkc's dataset doctor beside `lerobot-doctor` on the same LeRobot datasets (issue 22; a note,
not a test; results in book/src/doctor.md).

    .venv/bin/python bench/doctor_compare.py [--g1 PATH] [--seeds 0 1 2] [--work DIR]
    .venv/bin/python bench/doctor_compare.py --tracking [--seeds 0 1 2]

For each synthetic fault set (`chunkc synth --format lerobot`, 200 episodes, the seven faults of
tests/python/test_doctor.py each in its own known 10%) and, given `--g1`, the LeRobot G1 set
(e.g. ../shared/data/lerobot-g1), it runs `chunkc audit` (the doctor's flags per episode in
`audit.json`) and `lerobot-doctor check --json` (every message that is not PASS), and prints:
per fault kind, the injected episodes each tool flags; then each tool's findings on G1.

`--tracking` does the same on tests/python/tracking_set.py's sets (issue 30: a state that tracks
the commanded action, spikes and degrees-for-radians planted by a generator independent of
chunkc's): per doctor flag, chunkc's true positives, misses and false flags, and every
lerobot-doctor finding that is not PASS.
"""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BIN = Path(os.environ.get("CHUNKC_BIN", REPO / "target" / "release" / "chunkc"))
DOCTOR = Path(sys.executable).parent / "lerobot-doctor"
sys.path.insert(0, str(REPO / "tests" / "python"))
from test_doctor import DOCTOR_FLAGS, FAULTS, FLAG_OF  # noqa: E402


def run(*cmd):
    p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if p.returncode not in (0, 1):  # lerobot-doctor exits 1 when it finds something
        raise SystemExit(f"{' '.join(map(str, cmd))} failed ({p.returncode}):\n{p.stderr[-3000:]}")
    return p.stdout


def chunkc_flags(spec: Path, out: Path):
    run(BIN, "audit", spec)
    audit = json.loads((out / "audit" / "audit.json").read_text())
    flagged = {}
    for e in audit["episodes"]:
        for f in e["flags"]:
            flagged.setdefault(f, set()).add(e["id"])
    return flagged, audit


def lerobot_doctor(root: Path):
    report = json.loads(run(DOCTOR, "check", root, "--json"))
    return [(c["name"], m["severity"], m["message"]) for c in report["checks"]
            for m in c["messages"] if m["severity"] != "PASS"]


def tracking(seeds, work):
    sys.path.insert(0, str(REPO / "tests" / "python"))
    import tracking_set

    rows = {flag: [0, 0, 0] for flag in sorted(DOCTOR_FLAGS)}
    ld_all = set()
    for seed in seeds:
        root = work / f"tracking-{seed}"
        if not (root / "truth.json").exists():
            tracking_set.write(root, episodes=200, seed=seed)
        truth = {}
        for ep, injected in json.loads((root / "truth.json").read_text())["episodes"].items():
            for f in injected:
                truth.setdefault({"spike": "jump", "units": "units"}[f["kind"]], set()).add(int(ep))
        spec = work / f"tracking-{seed}.toml"
        spec.write_text(f'version = 1\n[source]\nformat = "lerobot"\npath = "{root}"\n'
                        '[source.channels]\naction = "action"\n"observation.state" = "observation.state"\n'
                        f'[output]\ndir = "{root}-out"\n[profiles.act]\npreset = "act"\nfps = 10\nchunk = 10\n')
        flagged, _ = chunkc_flags(spec, Path(f"{root}-out"))
        for flag, row in rows.items():
            t, got = truth.get(flag, set()), flagged.get(flag, set())
            row[0] += len(t & got)
            row[1] += len(t - got)
            row[2] += len(got - t)
        ld_all |= {f"{name}: {sev} {msg}" for name, sev, msg in lerobot_doctor(root)}
    print(f"Tracking sets, seeds {seeds} (200 episodes each; spikes and units each in 10%)\n")
    print("| flag | true positives | missed | false positives | recall | precision | lerobot-doctor |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for flag, (tp, fn, fp) in rows.items():
        rec = f"{tp / (tp + fn):.3f}" if tp + fn else "-"
        prec = f"{tp / (tp + fp):.3f}" if tp + fp else "-"
        print(f"| `{flag}` | {tp} | {fn} | {fp} | {rec} | {prec} | flags no episode |")
    print("\nlerobot-doctor's findings that are not PASS, on all the tracking sets:")
    for line in sorted(ld_all):
        print(f"- {line}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tracking", action="store_true",
                    help="the tracking sets of tests/python/tracking_set.py instead")
    ap.add_argument("--g1", type=Path)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--work", type=Path, default=Path("/tmp/chunkc-doctor-compare"))
    args = ap.parse_args()
    work = args.work.resolve()
    if args.tracking:
        work.mkdir(parents=True, exist_ok=True)
        return tracking(args.seeds, work)
    totals = {flag: [0, 0, 0] for flag in FLAG_OF.values()}  # injected, chunkc found, false flags
    ld_all = set()
    for seed in args.seeds:
        out = work / f"s{seed}"
        if not (out / "spec.toml").exists():
            run(BIN, "synth", out, "--format", "lerobot", "--episodes", 200, "--steps", 150,
                "--action-dim", 6, "--state-dim", 6, "--fps", 10, "--seed", seed,
                "--faults", FAULTS, "--fault-fraction", 0.1)
        flagged, _ = chunkc_flags(out / "spec.toml", out / "out")
        truth = {}
        for ep, injected in json.loads((out / "faults.json").read_text())["episodes"].items():
            for f in injected:
                truth.setdefault(FLAG_OF[f["fault"]], set()).add(int(ep))
        for flag, t in totals.items():
            got = flagged.get(flag, set())
            t[0] += len(truth.get(flag, set()))
            t[1] += len(truth.get(flag, set()) & got)
            t[2] += len(got - truth.get(flag, set()))
        found = lerobot_doctor(out / "lerobot")
        ld_all |= {f"{name}: {sev} {msg}" for name, sev, msg in found}
    print(f"Synthetic sets, seeds {args.seeds} (200 episodes each; every fault in its own 10%)\n")
    print("| fault | chunkc flag | injected | chunkc flags | chunkc false flags | lerobot-doctor |")
    print("| --- | --- | --- | --- | --- | --- |")
    for kind, flag in FLAG_OF.items():
        injected, hit, false = totals[flag]
        print(f"| `{kind}` | `{flag}` | {injected} | {hit} | {false} | none |")
    print("\nlerobot-doctor's findings that are not PASS, on all the synthetic sets:")
    for line in sorted(ld_all):
        print(f"- {line}")
    if args.g1:
        g1 = args.g1.resolve()
        spec = work / "g1.toml"
        text = (REPO / "specs" / "lerobot_g1.toml").read_text()
        text = text.replace('path = "../tests/data/lerobot_g1_subset"', f'path = "{g1}"')
        text = text.replace('dir = "../out/lerobot_g1"', f'dir = "{work}/g1-out"')
        spec.write_text(text)
        flagged, audit = chunkc_flags(spec, work / "g1-out")
        doctor = audit.get("doctor", {})
        print(f"\nG1 ({g1}): chunkc flags per episode: "
              + (", ".join(f"{f}: {len(v)}" for f, v in sorted(flagged.items()) if f in DOCTOR_FLAGS) or "none"))
        print(f"  lag mode {doctor.get('lag_mode')}, convention {doctor.get('convention')}")
        for w in audit.get("warnings", []):
            if "doctor" in w or "dimension" in w or "shift" in w or "holds still" in w:
                print(f"  warning: {w[:300]}")
        print("lerobot-doctor on G1 (not PASS):")
        for name, sev, msg in lerobot_doctor(g1):
            print(f"- {name}: {sev} {msg[:300]}")


if __name__ == "__main__":
    main()
