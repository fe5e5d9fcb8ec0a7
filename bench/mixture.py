"""Training mixtures (issue 40): a two-source mixture's build against its sources built alone, and
the generated loader's weighted sampler against plain shuffling.

    .venv/bin/python bench/mixture.py [--repeat 5] [--scales 1,4,16,64,256] [--threads 2]
                                      [--chunkc target/release/chunkc]
                                      [--work /tmp/chunkc-bench-mixture]
                                      [--out bench/results-mixture.json] [--no-diagnose]

Sources: `own`, the vendored Unitree G1 LeRobot subset (8 episodes at 30 Hz, 26-wide action and
state), and `sim`, a Push-T zarr replay buffer at 10 Hz (action 2, state 5): the vendored subset
(20 episodes) at scale 1, and at scale k a synthetic copy with k times its episodes (written with
zarr-python: the vendored episodes k times over, copies after the first with Gaussian noise of
5% of each dimension's spread on `action` and `state`, so that they are not near-duplicates for
the dataset doctor; `keypoint` and `n_contacts` copied; `img` left out, no channel reads it; the
vendored chunking and compressor). `own` stays the G1 subset at every scale.

1. Builds (`chunkc build -q -j THREADS`, the DEFAULT spec otherwise: no `[split]`, `[audit]`,
   weights or balance): the mixture (`[sources.own]` + `[sources.sim]`, `[mixture] pad_to =
   { action = 32, "observation.state" = 32 }`) against `own` alone and `sim` alone (`[source]`
   specs), all with one profile `dp` (preset "diffusion_policy", fps 10, format "zarr"). Wall
   time, CPU time and peak RSS from `/usr/bin/time`, `--repeat` interleaved rounds, medians
   reported; `own + sim` and `mixture / (own + sim)` are taken per round (paired), then the
   median. Also `twin`: a mixture of the `sim` data twice (`[sources.sim]` + `[sources.sim_b]`,
   one width, nothing padded) against twice `sim` alone, `twin / (2 sim)` paired per round: what
   the mixture path costs beside the padding. Every build runs with `CHUNKC_TIMINGS=1`: the phases of the median run are kept.
   Peak RSS (the largest of the rounds) is compared at every pair of scales N and 4N, for the
   mixture and for `sim` alone (it should be flat in episodes). At the largest scale, unless
   `--no-diagnose`, the mixture and `sim` alone are also built with `[audit.doctor] enabled =
   false` (not the default spec; only to show where the mixture's extra time goes).
2. Loader: on the smallest scale's mixture `dp` profile (scale 1 by default), the generated loader's
   `ChunkedDataset(root, "train")`, read through a torch DataLoader (batch 64, 0 workers) with
   `sampler=ds.sampler(num_samples, seed=0)` against `shuffle=True` over the same dataset, for
   `--samples` samples (and at least `--min-seconds`), `--repeat` interleaved rounds. Where the
   loader has no `sampler` yet, "sampler" is null and only the shuffle rate is reported.

The binary is copied to /tmp/chunkc-bench first and the copy is run (a rebuild does not change it
under the benchmark). Writes `--out` (JSON: command, machine, date, every run) and prints a table.
"""

import argparse
import datetime
import importlib.util
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import zarr

REPO = Path(__file__).resolve().parent.parent
G1 = REPO / "tests" / "data" / "lerobot_g1_subset"
PUSHT = REPO / "tests" / "data" / "pusht_subset.zarr"
COPY = Path("/tmp/chunkc-bench")

PROFILE = '[profiles.dp]\npreset = "diffusion_policy"\nfps = 10\nformat = "zarr"\n'
OWN = (f'[{{t}}]\nformat = "lerobot"\npath = "{G1}"\n[{{t}}.channels]\naction = "action"\n'
       '"observation.state" = "observation.state"\n')
SIM = ('[{t}]\nformat = "diffusion_policy_zarr"\npath = "{path}"\nfps = 10\n[{t}.channels]\n'
       'action = "action"\n"observation.state" = "state"\n')
PAD = '[mixture]\npad_to = { action = 32, "observation.state" = 32 }\n'
NOISY = ("action", "state")


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def pusht_copy(work, scale):
    """The vendored Push-T subset at scale 1; at scale k a zarr replay buffer with its episodes k
    times over (cached by scale), copies after the first noisy on `action` and `state`."""
    if scale == 1:
        return PUSHT
    path = work / "data" / f"pusht-x{scale}.zarr"
    done = path / ".complete"
    if done.exists():
        return path
    shutil.rmtree(path, ignore_errors=True)
    log(f"writing {path.name}")
    src = zarr.open(str(PUSHT), mode="r")
    ends = src["meta/episode_ends"][:].astype(np.int64)
    lengths = np.diff(np.concatenate([[0], ends]))
    rng = np.random.default_rng(scale)
    root = zarr.open_group(str(path), mode="w")
    root.create_group("meta").array("episode_ends", np.cumsum(np.tile(lengths, scale)))
    data = root.create_group("data")
    for key in src["data"]:
        if key == "img":
            continue
        a = src["data"][key]
        values = a[:]
        spread = values.std(0)
        copies = [values] + [
            (values + rng.normal(0.0, 0.05, values.shape) * spread).astype(values.dtype)
            if key in NOISY else values for _ in range(scale - 1)]
        data.array(key, np.concatenate(copies), chunks=a.chunks, compressor=a.compressor)
    done.touch()
    return path


def write_spec(path, sources, out, mixture=""):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'version = 1\n{sources}{mixture}[output]\ndir = "{out}"\n{PROFILE}')
    return path


def timed_once(cmd, env=None):
    """Runs cmd under /usr/bin/time: wall (perf_counter around it: /usr/bin/time's is in 10 ms
    steps), cpu (s) and peak RSS (MiB) from /usr/bin/time, and chunkc's phase timings
    (`phases`: [name, wall s, the process's peak RSS MiB at the phase's end])."""
    out = Path("/tmp/chunkc-bench-mixture-time.txt")
    full = ["/usr/bin/time", "-o", str(out), "-f", "%e %U %S %M"] + [str(c) for c in cmd]
    start = time.perf_counter()
    proc = subprocess.run(full, env={**os.environ, **(env or {})}, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"failed: {' '.join(map(str, cmd))}\n{proc.stdout}\n{proc.stderr}")
    _, user, sys_, rss = out.read_text().split()[-4:]
    phases = []
    for line in proc.stderr.splitlines():
        if line.startswith("timing: "):
            name, rest = line[len("timing: "):].split("  ", 1)
            words = rest.split()  # "0.012 s wall 0.00 s cpu peak RSS 41 MiB"
            phases.append([name.strip(), float(words[0]), float(words[-2])])
    return {"wall_s": round(wall, 4), "cpu_s": float(user) + float(sys_),
            "peak_rss_mib": round(int(rss) / 1024, 1),
            "phases": phases}


def du(path):
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file())


class Build:
    """One spec built from scratch (its output and lock removed before every run)."""

    def __init__(self, label, spec, out, threads):
        self.label, self.spec, self.out, self.threads = label, spec, out, threads
        self.runs = []

    def clean(self):
        shutil.rmtree(self.out, ignore_errors=True)
        (self.spec.parent / "chunkc.lock").unlink(missing_ok=True)

    def run(self):
        self.clean()
        r = timed_once([COPY, "build", "-q", "-j", self.threads, self.spec], {"CHUNKC_TIMINGS": "1"})
        r["output_bytes"] = du(self.out)
        self.runs.append(r)
        return r


def builds_at(work, scale, threads, diagnose=False):
    """The cases at one scale: mixture, own alone, sim alone; with `diagnose` also the mixture
    and sim alone with `[audit.doctor] enabled = false` (not the default spec: where the time
    goes)."""
    sim = pusht_copy(work, scale)
    d = work / "runs" / f"x{scale}"
    cases = {}
    mix = OWN.format(t="sources.own") + SIM.format(t="sources.sim", path=sim)
    twin = SIM.format(t="sources.sim", path=sim) + SIM.format(t="sources.sim_b", path=sim)
    variants = [("mixture", mix, PAD), ("own", OWN.format(t="source"), ""),
                ("sim", SIM.format(t="source", path=sim), ""), ("twin", twin, "")]
    if diagnose:
        off = "[audit.doctor]\nenabled = false\n"
        variants += [("mixture_nodoctor", mix, PAD + off),
                     ("sim_nodoctor", SIM.format(t="source", path=sim), off)]
    for label, sources, mixture in variants:
        out = d / label / "out"
        spec = write_spec(d / label / "spec.toml", sources, out, mixture)
        cases[label] = Build(f"x{scale}_{label}", spec, out, threads)
    # Warm page cache: every source file read once.
    for root in (G1, sim):
        for p in Path(root).rglob("*"):
            if p.is_file():
                p.read_bytes()
    return sim, cases


def median_run(runs):
    return dict(sorted(runs, key=lambda r: r["wall_s"])[len(runs) // 2])


def paired_median(values):
    return round(statistics.median(values), 4) if values else None


def load_generated(profile):
    spec = importlib.util.spec_from_file_location("chunkc_bench_mixture_loader", profile / "loader.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def rate(loader, samples, min_seconds):
    """Samples/s reading `loader` (restarted at its end) for `samples` samples and `min_seconds`;
    the first batch is not timed."""
    it = iter(loader)
    next(it)
    seen, start = 0, time.perf_counter()
    while seen < samples or time.perf_counter() - start < min_seconds:
        try:
            batch = next(it)
        except StopIteration:
            it = iter(loader)
            continue
        seen += len(batch["action"])
    seconds = time.perf_counter() - start
    return {"samples": seen, "seconds": round(seconds, 4), "samples_per_s": round(seen / seconds, 1)}


def loader_bench(profile, samples, min_seconds, repeat, batch):
    import torch
    import torch.utils.data

    torch.set_num_threads(1)
    mod = load_generated(profile)
    ds = mod.ChunkedDataset(profile, "train")
    res = {"profile": str(profile), "windows_train": len(ds), "batch_size": batch, "num_workers": 0,
           "num_samples": samples, "min_seconds": min_seconds}
    has_sampler = hasattr(ds, "sampler")
    if not has_sampler:
        log("NOTE: the generated loader has no `ds.sampler` (the template edit has not landed in "
            "this binary): \"sampler\" is recorded as null, only the shuffle rate is measured")
    else:
        s = ds.sampler(samples, seed=0)
        res["sampler_type"] = f"{type(s).__module__}.{type(s).__qualname__}"
        res["sampler_is_torch"] = isinstance(s, torch.utils.data.Sampler)
        idx = np.asarray(getattr(s, "indices", list(s)), dtype=np.int64)
        if getattr(ds, "window_sources", None) is not None:
            freq = np.bincount(ds.window_sources[idx], minlength=len(ds.source_names)) / len(idx)
            res["source_names"] = list(ds.source_names)
            res["sampler_source_frequencies"] = [round(float(f), 4) for f in freq]
            res["meta_weights_train"] = ds.meta["mixture"]["weights"]["train"]
            res["window_share_train"] = [
                round(float(f), 4) for f in
                np.bincount(ds.window_sources, minlength=len(ds.source_names)) / len(ds)]
        t = time.perf_counter()
        for _ in range(10):
            ds.sampler(samples, seed=0)
        res["sampler_construction_s"] = round((time.perf_counter() - t) / 10, 5)
    runs = {"sampler": [], "shuffle": []}
    for r in range(repeat):
        if has_sampler:
            dl = torch.utils.data.DataLoader(ds, batch_size=batch, num_workers=0,
                                             sampler=ds.sampler(samples, seed=0))
            runs["sampler"].append(rate(dl, samples, min_seconds))
        gen = torch.Generator().manual_seed(0)
        dl = torch.utils.data.DataLoader(ds, batch_size=batch, num_workers=0, shuffle=True,
                                         generator=gen)
        runs["shuffle"].append(rate(dl, samples, min_seconds))
        log(f"  loader round {r + 1}: " + ", ".join(
            f"{k} {v[-1]['samples_per_s']:.0f}/s" for k, v in runs.items() if v))
    med = lambda rs: statistics.median(x["samples_per_s"] for x in rs)  # noqa: E731
    res["sampler"] = None if not has_sampler else {
        "samples_per_s": med(runs["sampler"]),
        "all_samples_per_s": [x["samples_per_s"] for x in runs["sampler"]]}
    res["shuffle"] = {"samples_per_s": med(runs["shuffle"]),
                      "all_samples_per_s": [x["samples_per_s"] for x in runs["shuffle"]]}
    res["sampler_vs_shuffle"] = None if not has_sampler else paired_median(
        [a["samples_per_s"] / b["samples_per_s"] for a, b in zip(runs["sampler"], runs["shuffle"])])
    return res


def machine():
    model = next((line.split(":", 1)[1].strip() for line in
                  Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name")),
                 platform.processor())
    return {"nproc": os.cpu_count(), "cpu_model": model, "platform": platform.platform(),
            "loadavg_1_5_15": [float(x) for x in Path("/proc/loadavg").read_text().split()[:3]],
            "chunkc": subprocess.run([str(COPY), "--version"], capture_output=True,
                                     text=True).stdout.strip()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--chunkc", type=Path, default=REPO / "target" / "release" / "chunkc",
                    help="the binary (copied to /tmp/chunkc-bench, the copy is run)")
    ap.add_argument("--repeat", type=int, default=5, help="rounds; medians reported (default 5)")
    ap.add_argument("--scales", default="1,4,16,64,256",
                    help="multiples of the Push-T subset's 20 episodes (comma-separated; peak RSS "
                    "is compared at every N / 4N pair; default 1,4,16,64,256)")
    ap.add_argument("--threads", type=int, default=2, help="chunkc -j (default 2)")
    ap.add_argument("--samples", type=int, default=20000, help="loader samples per timed read")
    ap.add_argument("--min-seconds", type=float, default=2.0)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--work", type=Path, default=Path("/tmp/chunkc-bench-mixture"))
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results-mixture.json")
    ap.add_argument("--no-diagnose", action="store_true",
                    help="skip the doctor-off builds at the largest scale (diagnostic only)")
    ap.add_argument("--keep", action="store_true", help="keep WORK's outputs (the synthetic "
                    "sources are always kept, cached by scale)")
    args = ap.parse_args()
    if not args.chunkc.exists():
        raise SystemExit(f"{args.chunkc} not found: run `cargo build --release` first")
    shutil.copy2(args.chunkc, COPY)
    scales = sorted({int(s) for s in args.scales.split(",")})
    repeat = max(1, args.repeat)
    work = args.work.resolve()
    (work / "runs").mkdir(parents=True, exist_ok=True)
    started = time.time()
    res = {"command": " ".join([Path(sys.executable).name, *sys.argv]),
           "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
           "binary": {"path": str(args.chunkc), "copy": str(COPY),
                      "mtime": datetime.datetime.fromtimestamp(
                          args.chunkc.stat().st_mtime, datetime.timezone.utc).isoformat(
                          timespec="seconds")},
           "machine_before": machine(), "repeat": repeat, "threads": args.threads,
           "spec": {"profile": PROFILE, "mixture": PAD, "defaults": "no [split], [audit], "
                    "weights or balance: the defaults (doctor on, val_fraction default)"},
           "cache": "warm (every source file read once before timing)",
           "scales": {}}

    for scale in scales:
        sim, cases = builds_at(work, scale, args.threads,
                               diagnose=scale == scales[-1] and not args.no_diagnose)
        eps = len(zarr.open(str(sim), mode="r")["meta/episode_ends"])
        log(f"scale x{scale} ({eps} sim episodes), {repeat} interleaved rounds")
        sums, ratios, cpu_sums = [], [], []
        for r in range(repeat):
            got = {k: c.run() for k, c in cases.items()}
            sums.append(got["own"]["wall_s"] + got["sim"]["wall_s"])
            cpu_sums.append(got["own"]["cpu_s"] + got["sim"]["cpu_s"])
            ratios.append(got["mixture"]["wall_s"] / sums[-1] if sums[-1] else float("nan"))
            log(f"  round {r + 1}: " + ", ".join(
                f"{k} {v['wall_s']:.2f} s {v['peak_rss_mib']:.0f} MiB" for k, v in got.items()))
        entry = {"sim_episodes": eps, "sim_rows": int(zarr.open(str(sim), mode="r")
                                                      ["meta/episode_ends"][-1]),
                 "sim_path": str(sim), "runs": {}}
        for k, c in cases.items():
            m = median_run(c.runs)
            m["walls_s"] = [x["wall_s"] for x in c.runs]
            m["peak_rss_all_mib"] = [x["peak_rss_mib"] for x in c.runs]
            entry["runs"][k] = m
        entry["own_plus_sim"] = {"wall_s": round(statistics.median(sums), 3),
                                 "cpu_s": round(statistics.median(cpu_sums), 3)}
        entry["mixture_over_sum_wall"] = paired_median(ratios)
        entry["twin_over_two_sims_wall"] = paired_median(
            [t["wall_s"] / (2 * m["wall_s"]) for t, m in zip(cases["twin"].runs, cases["sim"].runs)])
        if "mixture_nodoctor" in cases:
            entry["mixture_nodoctor_over_sim_nodoctor_wall"] = paired_median(
                [a["wall_s"] / b["wall_s"] for a, b in
                 zip(cases["mixture_nodoctor"].runs, cases["sim_nodoctor"].runs)])
        meta = json.loads((cases["mixture"].out / "dp" / "meta.json").read_text())
        entry["mixture_meta"] = {
            "weights": meta["mixture"]["weights"],
            "num_samples": {n: s["num_samples"] for n, s in meta["sources"].items()}}
        res["scales"][f"x{scale}"] = entry
        if scale == scales[0]:
            log("loader: sampler against shuffle")
            res["loader"] = loader_bench(cases["mixture"].out / "dp", args.samples,
                                         args.min_seconds, repeat, args.batch)
            res["loader"]["scale"] = f"x{scale}"
        if not args.keep:
            for c in cases.values():
                c.clean()

    # Peak RSS (largest of the rounds) at N and 4N sim episodes, every such pair of scales.
    res["peak_rss_4N_over_N"] = []
    for n in scales:
        if 4 * n in scales:
            a, b = res["scales"][f"x{n}"]["runs"], res["scales"][f"x{4 * n}"]["runs"]
            for k in ("mixture", "sim"):
                lo, hi = max(a[k]["peak_rss_all_mib"]), max(b[k]["peak_rss_all_mib"])
                res["peak_rss_4N_over_N"].append(
                    {"build": k, "N": f"x{n}", "4N": f"x{4 * n}", "N_mib": lo, "4N_mib": hi,
                     "ratio": round(hi / lo, 3)})
    res["machine_after"] = machine()
    res["total_s"] = round(time.time() - started, 1)
    args.out.write_text(json.dumps(res, indent=2) + "\n")

    print(f"\n{'scale':6} {'sim eps':>7} {'build':16} {'wall s':>8} {'cpu s':>7} {'RSS MiB':>8}")
    for key, e in res["scales"].items():
        for k in e["runs"]:
            r = e["runs"][k]
            print(f"{key:6} {e['sim_episodes']:7} {k:16} {r['wall_s']:8.3f} {r['cpu_s']:7.2f} "
                  f"{r['peak_rss_mib']:8.1f}")
        s = e["own_plus_sim"]
        print(f"{key:6} {e['sim_episodes']:7} {'own+sim':16} {s['wall_s']:8.3f} {s['cpu_s']:7.2f}"
              f"{'':9}  mixture/(own+sim) = {e['mixture_over_sum_wall']}")
        print(f"{'':31}twin (sim twice, one width, no padding): twin/(2 sim) = "
              f"{e['twin_over_two_sims_wall']}")
        if "mixture_nodoctor_over_sim_nodoctor_wall" in e:
            print(f"{'':31}doctor off: mixture/sim = "
                  f"{e['mixture_nodoctor_over_sim_nodoctor_wall']}")
    print()
    for p in res["peak_rss_4N_over_N"]:
        print(f"peak RSS {p['build']:8} {p['N']:>5} {p['N_mib']:6.1f} MiB -> {p['4N']:>5} "
              f"{p['4N_mib']:6.1f} MiB: 4N/N = {p['ratio']}")
    top = res["scales"][f"x{scales[-1]}"]["runs"]
    cols = [k for k in ("mixture", "own", "sim", "twin", "mixture_nodoctor", "sim_nodoctor")
            if k in top]
    print(f"\nphases at x{scales[-1]} (median run, CHUNKC_TIMINGS, wall s; a mixture has one "
          "open source + audit per source)")
    print(f"{'phase':36}" + "".join(f"{k:>17}" for k in cols))
    names = []
    for k in cols:
        for n, *_ in top[k]["phases"]:
            if n not in names:
                names.append(n)
    for n in names:
        vals = [sum(v for m, v, _ in top[k]["phases"] if m == n) if any(
            m == n for m, *_ in top[k]["phases"]) else None for k in cols]
        print(f"{n:36}" + "".join(f"{'-' if v is None else f'{v:.3f}':>17}" for v in vals))
    print(f"{'output MiB':36}" + "".join(f"{top[k]['output_bytes'] / 2**20:17.1f}" for k in cols))
    for k in ("mixture", "sim"):
        steps, last = [], 0.0
        for n, _, rss in top[k]["phases"]:
            if rss > last + 8:
                steps.append(f"{n} {rss:.0f}")
            last = max(last, rss)
        print(f"peak RSS of {k} at x{scales[-1]} rises (MiB, by phase): {', '.join(steps)}")
    lo = res["loader"]
    sampler = "null (no ds.sampler in this loader)" if lo["sampler"] is None else \
        f"{lo['sampler']['samples_per_s']:.0f} samples/s"
    print(f"loader ({lo['scale']}, batch {lo['batch_size']}, 0 workers): sampler {sampler}, "
          f"shuffle {lo['shuffle']['samples_per_s']:.0f} samples/s, "
          f"ratio {lo['sampler_vs_shuffle']}")
    if lo.get("sampler_source_frequencies"):
        print(f"  sampler source frequencies {lo['sampler_source_frequencies']} "
              f"(meta weights {lo['meta_weights_train']}, window share "
              f"{lo['window_share_train']})")
    print(f"\nload average before {res['machine_before']['loadavg_1_5_15']}, after "
          f"{res['machine_after']['loadavg_1_5_15']}; {res['total_s']} s; written to {args.out}")


if __name__ == "__main__":
    main()
