"""Spikes that return (issue 50): the `jump` check's recall on one-step spikes planted into real
episodes, per kind of dimension, and the flags it raises on the same data clean. A note, not a
test; results in book/src/doctor.md ("Calibrated on real data") and
bench/results-doctor-spikes.json.

    .venv/bin/python bench/doctor_spikes.py [--lerobot DIR ...] [--seeds 0 1 2 3 4]
        [--work DIR] [--json bench/results-doctor-spikes.json] [--only NAME ...]
        [--seeds 0 1 ... 19]

The datasets are the project's real ones, read here with numpy (so the truth never comes from
chunkc): the LeRobot G1 set (shared/data) and its 8-episode subset (tests/data), Push-T's replay
buffer, robosuite's Panda (one episode per task: six sets) and Sawyer (two per environment: four
sets) teleoperation, and the Bridge RLDS subset; `--lerobot DIR` adds LeRobot v2.1/v3.0 folders
(the calibration sets of bench/doctor_real.py, when they are on the machine). Each is written as
a Diffusion Policy zarr replay buffer (action and state, float32: the doctor's own precision)
and audited with `chunkc audit`:

1. clean: the episodes each doctor check flags;
2. planted, per seed: in a tenth of the episodes (at least one), a one-step spike in one action
   dimension: `x[t] += s` at a step `t` three or more from either end, the next step the
   recorded one, `|s|` 10%, 20% or 30% of the dimension's range over the dataset (either sign).
   A plant is caught when the episode's `jump` finding names its dimension (an episode has one
   finding per flag, hence one plant). Every dimension that moves over the dataset takes part,
   classed in its episode by how it moves:
   - `still`: unchanged from the step before in at least 80% of the steps (a joint at rest, a
     servo's ticks, a hand that holds);
   - `fast`: its 99th percentile step reaches a quarter of the spike; `fast-half`: half of it
     or more;
   - `moving`: the others.
   `jump` findings that name another dimension than the plant's, or an episode nothing was
   planted in, are counted too (beyond the clean run's).
   Each plant is also `separable` or `buried` ([`buried_levels`]): whether its own return is
   larger than what one clean episode in twenty reaches in that dimension anyway.
"""

import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pyarrow.parquet as pq
import zarr

REPO = Path(__file__).resolve().parent.parent
BIN = Path(os.environ.get("CHUNKC_BIN", REPO / "target" / "release" / "chunkc"))
SHARED = Path("/work/shared/data")
CHECKS = ["frozen", "clipped", "jump", "units", "misaligned", "mixed_convention", "duplicate"]
FRACTIONS = [0.1, 0.2, 0.3]


def lerobot(root: Path):
    """(fps, [(action, state)]) of a LeRobot v2.1 or v3.0 folder, episodes in index order."""
    info = json.loads((root / "meta" / "info.json").read_text())
    feats = info["features"]
    akey = next(k for k in ("action", "actions") if k in feats)
    skey = next((k for k in ("observation.state", "state") if k in feats), None)
    eps = {}
    for f in sorted((root / "data").rglob("*.parquet")):
        cols = ["episode_index", "frame_index", akey] + ([skey] if skey else [])
        t = pq.read_table(f, columns=cols)
        ep = t.column("episode_index").to_numpy()
        fr = t.column("frame_index").to_numpy()
        a = np.stack(t.column(akey).to_numpy(zero_copy_only=False)).astype(np.float64)
        s = np.stack(t.column(skey).to_numpy(zero_copy_only=False)).astype(np.float64) if skey else None
        for e in np.unique(ep):
            rows = np.where(ep == e)[0]
            rows = rows[np.argsort(fr[rows], kind="stable")]
            eps[int(e)] = (a[rows], None if s is None else s[rows])
    return info["fps"], [eps[e] for e in sorted(eps)]


def pusht(path: Path):
    g = zarr.open_group(str(path), mode="r")
    a, s = np.asarray(g["data/action"], np.float64), np.asarray(g["data/state"], np.float64)
    ends = np.asarray(g["meta/episode_ends"])
    starts = np.concatenate([[0], ends[:-1]])
    return 10, [(a[b:e], s[b:e]) for b, e in zip(starts, ends)]


def robosuite(path: Path, action, state_cols):
    """robosuite HDF5: `action` a key or a list of keys to concatenate; the state's columns."""
    out = []
    with h5py.File(path, "r") as f:
        for demo in sorted(f["data"], key=lambda k: int(k.split("_")[1])):
            g = f["data"][demo]
            keys = [action] if isinstance(action, str) else action
            a = np.concatenate([np.asarray(g[k], np.float64) for k in keys], axis=1)
            s = np.asarray(g["states"], np.float64)[:, state_cols[0]:state_cols[1]]
            out.append((a, s))
    return out


def bridge(root: Path):
    from tfrecord import example_pb2
    from tfrecord.reader import tfrecord_iterator

    out = []
    for split in ("train", "val"):
        for f in sorted(glob.glob(str(root / f"*-{split}.tfrecord-*"))):
            for rec in tfrecord_iterator(f):
                ex = example_pb2.Example()
                ex.ParseFromString(rec)
                feat = ex.features.feature
                a = np.asarray(feat["steps/action"].float_list.value, np.float64).reshape(-1, 7)
                s = np.asarray(feat["steps/observation/state"].float_list.value, np.float64).reshape(-1, 7)
                out.append((a, s))
    return 5, out


def datasets(extra):
    """name -> a function returning (fps, episodes)."""
    sets = {
        "lerobot-g1": lambda: lerobot(SHARED / "lerobot-g1"),
        "lerobot_g1_subset": lambda: lerobot(REPO / "tests" / "data" / "lerobot_g1_subset"),
        "pusht": lambda: pusht(SHARED / "pusht" / "pusht_cchi_v7_replay.zarr"),
        "bridge": lambda: bridge(SHARED / "rlds-bridge" / "bridge_dataset" / "1.0.0"),
    }
    for task in ("door", "lift", "nut-assembly", "pick-place", "stack", "wipe"):
        p = SHARED / "robosuite-panda" / task / "panda" / "demo.hdf5"
        sets[f"robosuite-panda-{task}"] = lambda p=p: (20, robosuite(p, "actions", (1, None)))
    for env in ("SawyerLift", "SawyerNutAssembly", "SawyerPickPlace", "SawyerStack"):
        p = SHARED / "robosuite-sawyer" / env / "demo.hdf5"
        sets[f"robosuite-sawyer-{env}"] = lambda p=p: (
            100, robosuite(p, ["joint_velocities", "gripper_actuations"], (1, None)))
    for d in extra:
        sets[Path(d).resolve().name] = lambda d=d: lerobot(Path(d).resolve())
    return sets


def write_zarr(path: Path, episodes):
    if path.exists():
        shutil.rmtree(path)
    g = zarr.open_group(str(path), mode="w")
    a = np.concatenate([e[0] for e in episodes]).astype(np.float32)
    g.create_dataset("data/action", data=a, chunks=(min(len(a), 4096), a.shape[1]))
    if episodes[0][1] is not None:
        s = np.concatenate([e[1] for e in episodes]).astype(np.float32)
        g.create_dataset("data/state", data=s, chunks=(min(len(s), 4096), s.shape[1]))
    ends = np.cumsum([len(e[0]) for e in episodes]).astype(np.int64)
    g.create_dataset("meta/episode_ends", data=ends)


def audit(work: Path, name: str, fps, episodes):
    """{episode: [finding]} of `chunkc audit` over `episodes` written as a zarr replay buffer."""
    src = work / f"{name}.zarr"
    out = work / f"{name}-out"
    write_zarr(src, episodes)
    lines = ["version = 1", "[source]", 'format = "diffusion_policy_zarr"', f'path = "{src}"',
             f"fps = {fps}", "[source.channels]", 'action = "action"']
    if episodes[0][1] is not None:
        lines.append('"observation.state" = "state"')
    lines += ["[output]", f'dir = "{out}"', "[profiles.act]", 'preset = "act"', f"fps = {fps}",
              "chunk = 4"]
    spec = work / f"{name}.toml"
    spec.write_text("\n".join(lines) + "\n")
    p = subprocess.run([str(BIN), "audit", str(spec)], capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"chunkc audit {spec} failed:\n{p.stderr[-3000:]}")
    report = json.loads((out / "audit" / "audit.json").read_text())
    return {e["id"]: e for e in report["episodes"]}


def flags_of(report):
    """{check: sorted episodes}."""
    out = {c: [] for c in CHECKS}
    for e, ep in report.items():
        for f in ep["flags"]:
            out.setdefault(f, []).append(e)
    return {c: sorted(v) for c, v in out.items()}


def jump_dims(ep):
    """{dim: step} of an episode's `jump` findings."""
    out = {}
    for f in ep.get("findings", []):
        if f.get("flag") == "jump":
            ev = f.get("evidence", {})
            out[int(ev["dim"])] = int(ev["step"])
    return out


def classify(x, size):
    steps = np.abs(np.diff(x))
    if np.mean(steps == 0) >= 0.8:
        return "still"
    p99 = np.quantile(steps, 0.99)
    if p99 >= 0.5 * abs(size):
        return "fast-half"
    if p99 >= 0.25 * abs(size):
        return "fast"
    return "moving"


def returns_of(x):
    """How far `x` goes out and straight back at each interior step t (the lesser of its two
    steps when they have opposite signs, else 0)."""
    up, down = x[1:-1] - x[:-2], x[2:] - x[1:-1]
    return np.where(up * down < 0, np.minimum(np.abs(up), np.abs(down)), 0.0)


def buried_levels(episodes):
    """Per action dimension, the 95th percentile over the clean episodes of each episode's
    largest return ([`returns_of`]): a plant whose own return is no larger cannot be told by its
    return from what 5% or more of the clean episodes do (the check's precision goal)."""
    dims = episodes[0][0].shape[1]
    largest = np.array([[returns_of(a[:, d]).max() if len(a) >= 3 else 0.0 for d in range(dims)]
                        for a, _ in episodes])
    return np.quantile(largest, 0.95, axis=0)


def plan(episodes, rng):
    """[(episode, dim, step, size, fraction, class)]: a spike in each of a tenth of the
    episodes."""
    allv = np.concatenate([e[0] for e in episodes])
    span = allv.max(0) - allv.min(0)
    dims = [d for d in range(allv.shape[1]) if span[d] > 0]
    order = [int(e) for e in rng.permutation(len(episodes)) if len(episodes[e][0]) >= 7]
    out = []
    for e in order[:max(1, round(0.1 * len(episodes)))]:
        x = episodes[e][0]
        n = len(x)
        d = int(rng.choice(dims))
        t = int(rng.integers(3, n - 3))
        frac = float(rng.choice(FRACTIONS))
        size = frac * span[d] * (1 if rng.random() < 0.5 else -1)
        out.append((e, d, t, size, frac, classify(x[:, d], size)))
    return out


def planted(episodes, spikes):
    eps = [(a.copy(), s) for a, s in episodes]
    for e, d, t, size, _, _ in spikes:
        eps[e][0][t, d] += size
    return eps


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--lerobot", nargs="*", default=[])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(20)))
    ap.add_argument("--work", type=Path, default=Path("/tmp/doctor-spikes"))
    ap.add_argument("--json", type=Path)
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--quiet", action="store_true", help="do not list the misses")
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    results = {}
    total = {}
    for name, load in datasets(args.lerobot).items():
        if args.only and name not in args.only:
            continue
        fps, episodes = load()
        clean = audit(args.work, name, fps, episodes)
        buried = buried_levels(episodes)
        res = {"episodes": len(episodes), "action_dims": episodes[0][0].shape[1],
               "clean": flags_of(clean), "plants": [], "other_jump": 0}
        for seed in args.seeds:
            rng = np.random.default_rng(seed)
            spikes = plan(episodes, rng)
            got = audit(args.work, f"{name}-planted", fps, planted(episodes, spikes))
            planted_at = {(e, d) for e, d, *_ in spikes}
            for e, d, t, size, frac, cls in spikes:
                found = jump_dims(got[e])
                hit = d in found
                x = episodes[e][0][:, d].copy()
                x[t] += size
                own = float(returns_of(x[t - 1:t + 2])[0])
                res["plants"].append({"episode": e, "dim": d, "step": t, "size": size,
                                      "fraction": frac, "class": cls, "caught": hit,
                                      "separable": bool(own > buried[d])})
                if not hit and not args.quiet:
                    x = episodes[e][0][:, d]
                    steps = np.abs(np.diff(x))
                    print(f"  missed {name} ep {e} dim {d} step {t} size {size:+.4g} ({frac:.0%}, "
                          f"{cls}; p99 step {np.quantile(steps, 0.99):.4g}, max step {steps.max():.4g}; clean "
                          f"around {np.round(x[t - 3:t + 4], 4).tolist()})")
            # `jump` findings on dimensions nothing was planted in, beyond the clean run's.
            for e, ep in got.items():
                for d in jump_dims(ep):
                    if (e, d) not in planted_at and d not in jump_dims(clean[e]):
                        res["other_jump"] += 1
        by = {}
        for p in res["plants"]:
            keys = [p["class"], f"{p['fraction']:.0%}", "all"]
            keys += ["separable"] if p["separable"] else ["buried"]
            keys += [f"separable {p['class']}"] if p["separable"] else []
            for key in keys:
                h = by.setdefault(key, [0, 0])
                h[0] += p["caught"]
                h[1] += 1
                t = total.setdefault(key, [0, 0])
                t[0] += p["caught"]
                t[1] += 1
        res["recall"] = by
        # The misses alone, to keep the file small.
        res["missed"] = [p for p in res.pop("plants") if not p["caught"]]
        results[name] = res
        flagged = ", ".join(f"{c} {len(v)}" for c, v in res["clean"].items() if v) or "nothing"
        print(f"{name}: {len(episodes)} episodes, {res['action_dims']}-D; clean flags {flagged}; "
              "recall " + ", ".join(f"{k} {h}/{n}" for k, (h, n) in sorted(by.items()))
              + f"; other jump findings {res['other_jump']}", flush=True)
    print("\nall: " + ", ".join(f"{k} {h}/{n} ({h / max(n, 1):.2f})" for k, (h, n) in sorted(total.items())))
    if args.json:
        args.json.write_text(json.dumps({"datasets": results, "recall": total}, indent=1,
                                        sort_keys=True) + "\n")


if __name__ == "__main__":
    sys.exit(main())
