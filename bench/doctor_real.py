"""The dataset doctor on real LeRobot datasets (issue 37): per-check flag rates on the data as
published, and the recall of faults planted into copies of its real episodes. A note, not a test;
results in book/src/doctor.md ("Calibrated on real data").

    .venv/bin/python bench/doctor_real.py DATASET [DATASET ...] [--work DIR] [--seeds 0 1 2]
        [--json bench/results-doctor-real.json]

Each DATASET is a LeRobot v2.1 or v3.0 folder (meta/info.json, data/...). The action is the
feature named `action` (or `actions`), the state `observation.state` (or `state`); cameras are not
read. For each:

1. clean: `chunkc audit` of the dataset as published; the share of episodes each doctor flag
   marks (a clean real dataset should mark few: the book states the goal, 5% per check);
2. planted: for every seed, a copy of the low-dim parquet files with four kinds of fault, each in
   its own randomly chosen episodes (about 10% each, at least one), written by this script alone
   (the truth never comes from the doctor):
   - `spike`: one step of one moving action dimension moved by 10-30% of that dimension's range
     over the dataset, and straight back (the next step is the recorded one);
   - `units`: the episode's action in degrees where the rest are radians (x 180/pi);
   - `frozen`: one action dimension that moves through the episode (no run of one value over
     30% of it) holds its value from a random step for 50-80% of the episode (a hung
     actuator's command);
   - `lag`: the action logged 3 steps late against the state (`a'[t] = a[t-3]`, the first
     repeated);
   then `chunkc audit` and, per kind, the share of planted episodes flagged with its flag
   (`jump`, `units`, `frozen`, `misaligned`), and the flags on episodes nothing was planted in.
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

REPO = Path(__file__).resolve().parent.parent
BIN = Path(os.environ.get("CHUNKC_BIN", REPO / "target" / "release" / "chunkc"))
FLAG_OF = {"spike": "jump", "units": "units", "frozen": "frozen", "lag": "misaligned"}
CHECKS = ["frozen", "clipped", "jump", "units", "misaligned", "mixed_convention", "duplicate"]


def keys(info):
    feats = info["features"]
    action = next(k for k in ("action", "actions") if k in feats)
    state = next((k for k in ("observation.state", "state") if k in feats), None)
    return action, state


def spec_for(root: Path, out: Path, info) -> str:
    action, state = keys(info)
    lines = ["version = 1", "[source]", 'format = "lerobot"', f'path = "{root}"',
             "[source.channels]", f'action = "{action}"']
    if state:
        lines.append(f'"observation.state" = "{state}"')
    lines += ["[output]", f'dir = "{out}"', "[profiles.act]", 'preset = "act"',
              f"fps = {info['fps']}", "chunk = 10"]
    return "\n".join(lines) + "\n"


def audit(root: Path, work: Path, name: str, info):
    spec = work / f"{name}.toml"
    out = work / f"{name}-out"
    spec.write_text(spec_for(root, out, info))
    p = subprocess.run([str(BIN), "audit", str(spec)], capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"chunkc audit {spec} failed:\n{p.stderr[-3000:]}")
    report = json.loads((out / "audit" / "audit.json").read_text())
    flagged = {}
    for e in report["episodes"]:
        for f in e["flags"]:
            flagged.setdefault(f, set()).add(e["id"])
    return flagged, report


def data_files(root: Path):
    return sorted((root / "data").rglob("*.parquet"))


def column(table, name):
    col = table.column(name).combine_chunks()
    width = col.type.list_size if pa.types.is_fixed_size_list(col.type) else None
    values = np.asarray(col.flatten().to_numpy(zero_copy_only=False), dtype=np.float64)
    n = len(col)
    return values.reshape(n, -1).copy(), col.type, width


def put(table, name, values, typ):
    flat = pa.array(values.astype(np.float32).ravel(), type=typ.value_type)
    if pa.types.is_fixed_size_list(typ):
        arr = pa.FixedSizeListArray.from_arrays(flat, typ.list_size)
    else:
        width = values.shape[1]
        offsets = pa.array(np.arange(0, width * (len(values) + 1), width, dtype=np.int32))
        arr = pa.ListArray.from_arrays(offsets, flat)
    i = table.schema.get_field_index(name)
    return table.set_column(i, table.schema.field(i), arr)


def load(root: Path, action_key: str):
    """Every episode's action rows: {episode: array (n, A)} (in step order)."""
    eps = {}
    for f in data_files(root):
        t = pq.read_table(f, columns=["episode_index", "frame_index", action_key])
        a, _, _ = column(t, action_key)
        ep = t.column("episode_index").to_numpy()
        fr = t.column("frame_index").to_numpy()
        for e in np.unique(ep):
            rows = np.where(ep == e)[0]
            rows = rows[np.argsort(fr[rows], kind="stable")]
            eps[int(e)] = a[rows]
    return eps


def longest_run(x):
    """The longest run of one exact value in `x`."""
    change = np.flatnonzero(np.diff(x) != 0)
    bounds = np.concatenate([[-1], change, [len(x) - 1]])
    return int(np.diff(bounds).max())


def plan_faults(eps, rng):
    """{episode: (kind, params)} for about 10% of the episodes per kind, disjoint."""
    ids = sorted(eps)
    allv = np.concatenate([eps[e] for e in ids])
    rng_d = allv.max(0) - allv.min(0)
    per = max(1, round(0.1 * len(ids)))
    order = list(rng.permutation(ids))
    plan = {}
    for kind in ["spike", "units", "frozen", "lag"]:
        for _ in range(per):
            if not order:
                break
            e = int(order.pop())
            x = eps[e]
            n = len(x)
            moving = [d for d in range(x.shape[1]) if rng_d[d] > 0 and np.ptp(x[:, d]) > 0.05 * rng_d[d]]
            # A freeze is a fault where the dimension moves through the episode: in one that
            # holds still anyway (an idle arm, a hand holding its grasp) it is the normal.
            if kind == "frozen":
                moving = [d for d in moving if longest_run(x[:, d]) < 0.3 * n]
            if kind in ("spike", "frozen") and (not moving or n < 20):
                continue
            if kind == "spike":
                d = int(rng.choice(moving))
                t = int(rng.integers(3, n - 3))
                size = float(rng.uniform(0.1, 0.3) * rng_d[d]) * (1 if rng.random() < 0.5 else -1)
                plan[e] = ("spike", {"dim": d, "step": t, "size": size})
            elif kind == "frozen":
                d = int(rng.choice(moving))
                length = int(rng.uniform(0.5, 0.8) * n)
                start = int(rng.integers(0, n - length + 1))
                plan[e] = ("frozen", {"dim": d, "start": start, "length": length})
            elif kind == "units":
                plan[e] = ("units", {"factor": 180 / math.pi})
            else:
                plan[e] = ("lag", {"steps": 3})
    return plan


def apply(x, kind, p):
    x = x.copy()
    if kind == "spike":
        x[p["step"], p["dim"]] += p["size"]
    elif kind == "frozen":
        s, L = p["start"], p["length"]
        x[s:s + L, p["dim"]] = x[s, p["dim"]]
    elif kind == "units":
        x *= p["factor"]
    else:
        k = p["steps"]
        x = np.concatenate([np.repeat(x[:1], k, 0), x[:-k]])
    return x


def planted_copy(root: Path, dst: Path, action_key: str, plan):
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(root / "meta", dst / "meta")
    for f in data_files(root):
        t = pq.read_table(f)
        a, typ, _ = column(t, action_key)
        ep = t.column("episode_index").to_numpy()
        fr = t.column("frame_index").to_numpy()
        for e, (kind, p) in plan.items():
            rows = np.where(ep == e)[0]
            if len(rows) == 0:
                continue
            rows = rows[np.argsort(fr[rows], kind="stable")]
            a[rows] = apply(a[rows], kind, p)
        t = put(t, action_key, a, typ)
        out = dst / f.relative_to(root)
        out.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(t, out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("datasets", nargs="+", type=Path)
    ap.add_argument("--work", type=Path, default=Path("/tmp/doctor-real"))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--json", type=Path)
    ap.add_argument("--clean-only", action="store_true")
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    results = {}
    recall_all = {k: [0, 0] for k in FLAG_OF}
    for root in args.datasets:
        root = root.resolve()
        name = root.name
        info = json.loads((root / "meta" / "info.json").read_text())
        action_key, _ = keys(info)
        flagged, report = audit(root, args.work, name, info)
        n = len(report["episodes"])
        rates = {c: len(flagged.get(c, ())) / n for c in CHECKS}
        res = {"episodes": n, "clean": {c: sorted(flagged.get(c, ())) for c in CHECKS},
               "rates": rates, "warnings": report.get("warnings", [])}
        print(f"\n== {name}: {n} episodes, action {info['features'][action_key]['shape']}")
        print("  clean: " + ", ".join(f"{c} {len(flagged.get(c, ()))} ({100 * r:.0f}%)" for c, r in rates.items()))
        for w in report.get("warnings", []):
            print(f"    warning: {w[:200]}")
        if not args.clean_only:
            eps = load(root, action_key)
            recall = {k: [0, 0] for k in FLAG_OF}
            false = {c: 0 for c in CHECKS}
            judged = 0
            for seed in args.seeds:
                rng = np.random.default_rng(seed)
                plan = plan_faults(eps, rng)
                dst = args.work / f"{name}-planted-{seed}"
                planted_copy(root, dst, action_key, plan)
                got, _ = audit(dst, args.work, f"{name}-planted-{seed}", info)
                for e, (kind, p) in plan.items():
                    hit = e in got.get(FLAG_OF[kind], set())
                    recall[kind][0] += hit
                    recall[kind][1] += 1
                    recall_all[kind][0] += hit
                    recall_all[kind][1] += 1
                    if not hit:
                        print(f"    missed {kind} in episode {e}: {p}")
                for c in CHECKS:
                    false[c] += len(got.get(c, set()) - set(plan))
                judged += n - len(plan)
            res["recall"] = {k: v for k, v in recall.items()}
            res["false_on_unplanted"] = {c: false[c] / max(judged, 1) for c in CHECKS}
            print("  planted recall: " + ", ".join(f"{k} {h}/{t}" for k, (h, t) in recall.items()))
            print("  flags on unplanted episodes: " + ", ".join(f"{c} {100 * v:.0f}%" for c, v in res["false_on_unplanted"].items()))
        results[name] = res
    if not args.clean_only:
        print("\nall datasets, planted recall: " + ", ".join(
            f"{k} {h}/{t} ({h / max(t, 1):.2f})" for k, (h, t) in recall_all.items()))
    if args.json:
        args.json.write_text(json.dumps({"datasets": results, "recall": recall_all}, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    sys.exit(main())
