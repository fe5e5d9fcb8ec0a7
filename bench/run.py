"""chunkc's benchmark harness: one command, same generated data, one table of ratios.

    .venv/bin/python bench/run.py [--quick] [--work /tmp/chunkc-bench] [--out bench/results.json]

Generates ALOHA-layout sources with `chunkc synth` (cached under WORK/data by their parameters),
then measures wall time, CPU time (user + sys) and peak RSS (`/usr/bin/time`) of:

1. chunkc building one `act` profile (index layout), low-dim and with images;
2. chunkc building 4 profiles at 4 rates from one spec, against 1 profile;
   chunkc with 1 thread against 2 threads (low-dim);
   chunkc on N and 2N episodes (low-dim) and N/2 and N (images) for peak RSS;
3. bench/numpy_pipeline.py doing the same work with numpy + h5py;
4. the I/O floor: `cat` of every source file to /dev/null, then `cat` of chunkc's output files
   into one file with `dd conv=fsync` (chunkc fsyncs its outputs too);
5. bench/loader_bench.py: samples/s of the generated loader (0 and 2 workers, and in memory)
   against an open-the-file-per-item Dataset (ACT's pattern) and in-memory numpy chunks.

`--only zarr` measures the same low-dim work on Diffusion Policy zarr replay buffers (N episodes
of 400 steps, 14-D action and state, generated with `chunkc synth --format diffusion-policy-zarr`)
in three chunkings: one chunk per episode (`episode`), 36,000-row chunks (Diffusion Policy's
~2 MB target, `dp`), and zarr-python's default for a (2,000,000, 14) float32 array, (125000, 2)
(`zarr_default`, which also splits the columns). chunkc builds with the DEFAULT spec (the
dataset doctor on, as every user gets it) and, beside it, with `[audit.doctor] enabled = false`
(issue 30: the doctor may add at most 15%); on the one-chunk-per-episode layout also with one
thread, both ways. Per layout: chunkc, the numpy pipeline
(`--zarr`: zarr-python reads each array whole), the I/O floor, and chunkc on N/2 episodes (peak
RSS flat from N/2 to N).

Every measurement runs `--repeat` times (5 by default), interleaved: each round runs every
measurement of a group once (low-dim: numpy, chunkc 1 profile, the I/O floor, 1 thread, two
independent 1-thread builds at once, 4 profiles, 2N; images: numpy, chunkc, the floor, N/2;
the loader's six), so that a machine whose speed drifts over minutes (a shared VM) slows both
sides of a ratio alike. The run with the median wall time (median samples/s for the loader) is
reported, and each ratio is the median of the ratios within a round; every run's number is kept
in the JSON, in round order. The page cache is warm (each source is read once before its
group); dropping caches needs privileges the harness does not assume (`cache` in the JSON says
which). Generated data stays under about 6 GB (N/2 and 2N datasets are symlinks to the N
files); outputs are deleted as the measurements go. `--clean` removes WORK at the end.
"""

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BIN = REPO / "target" / "release" / "chunkc"
PY = sys.executable

SIZES = {
    "full": {"lowdim": dict(episodes=5000, steps=400), "images": dict(episodes=200, steps=300),
             "loader_episodes": 40, "loader_samples": 3000},
    "quick": {"lowdim": dict(episodes=200, steps=400), "images": dict(episodes=10, steps=300),
              "loader_episodes": 6, "loader_samples": 600},
}
DIMS = dict(action_dim=14, state_dim=14, fps=50, seed=0)

ONE = '[profiles.act]\npreset = "act"\nfps = 50\nchunk = 100\nformat = "hdf5"\n'
FOUR = ONE + (
    '[profiles.act25]\npreset = "act"\nfps = 25\nchunk = 50\nformat = "hdf5"\n'
    '[profiles.dp]\npreset = "diffusion_policy"\nfps = 10\nformat = "hdf5"\n'
    '[profiles.pi5]\npreset = "openpi"\nfps = 5\nchunk = 10\nformat = "hdf5"\n')


def log(msg):
    print(msg, file=sys.stderr, flush=True)


REPEAT = 5


def timed_once(cmd, env=None, cwd=None):
    """Runs cmd under /usr/bin/time; returns wall, cpu (s) and peak RSS (MiB) of the command."""
    out = Path("/tmp/chunkc-bench-time.txt")
    full = ["/usr/bin/time", "-o", str(out), "-f", "%e %U %S %M"] + [str(c) for c in cmd]
    proc = subprocess.run(full, env={**os.environ, **(env or {})}, cwd=cwd, capture_output=True,
                          text=True)
    if proc.returncode != 0:
        raise SystemExit(f"failed: {' '.join(map(str, cmd))}\n{proc.stdout}\n{proc.stderr}")
    wall, user, sys_, rss = out.read_text().split()[-4:]
    return {"wall_s": float(wall), "cpu_s": float(user) + float(sys_),
            "peak_rss_mib": int(rss) / 1024, "stdout": proc.stdout}


def du(path):
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file())


def synthesized(work, name, params, args):
    """`chunkc synth` into work/data/<name>-<params>, once: later calls with the same parameters
    reuse it."""
    key = "-".join(f"{k}{v}" for k, v in sorted(params.items()))
    root = work / "data" / f"{name}-{key}"
    if not (root / "spec.toml").exists():
        if root.exists():
            shutil.rmtree(root)
        log(f"generating {root.name}")
        cmd = [BIN, "synth", root, "--action-dim", DIMS["action_dim"], "--state-dim",
               DIMS["state_dim"], "--fps", DIMS["fps"], "--seed", DIMS["seed"], *args]
        subprocess.run([str(c) for c in cmd], check=True)
    return root


def synth(work, name, episodes, steps, cameras):
    params = dict(DIMS, episodes=episodes, steps=steps, cameras=cameras)
    return synthesized(work, name, params, [
        "--format", "aloha-hdf5", "--episodes", episodes, "--steps", steps, "--cameras", cameras,
        "--resolution", "96x96"])


ZARR_LAYOUTS = {"episode": dict(rows=400), "dp": dict(rows=36000),
                "zarr_default": dict(rows=125000, cols=2)}


def synth_zarr(work, layout, episodes, steps):
    """A Diffusion Policy zarr replay buffer in one of ZARR_LAYOUTS (cached by parameters)."""
    chunking = ZARR_LAYOUTS[layout]
    args = ["--format", "diffusion-policy-zarr", "--episodes", episodes, "--steps", steps,
            "--zarr-chunk-rows", chunking["rows"]]
    if "cols" in chunking:
        args += ["--zarr-chunk-cols", chunking["cols"]]
    return synthesized(work, f"zarr-{layout}", dict(DIMS, episodes=episodes, steps=steps, **chunking),
                       args)


def zarr_spec(root, out, doctor=True):
    """The DEFAULT spec (the dataset doctor on), or with `[audit.doctor] enabled = false`."""
    off = "" if doctor else "[audit.doctor]\nenabled = false\n"
    text = (f'version = 1\n[source]\nformat = "diffusion_policy_zarr"\n'
            f'path = "{root / "replay.zarr"}"\nfps = 50\n[source.channels]\naction = "action"\n'
            f'"observation.state" = "state"\n{off}'
            f'[split]\nval_fraction = 0.1\nseed = 0\n[output]\ndir = "{out}"\n{ONE}')
    path = out.parent / f"{out.name}.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def zarr_chunkc(work, label, root, doctor=True, threads=2):
    out = work / "runs" / label
    path = zarr_spec(root, out, doctor)
    lock = out.parent / "chunkc.lock"

    def clean():
        shutil.rmtree(out, ignore_errors=True)
        lock.unlink(missing_ok=True)

    clean()
    return Case(label, [BIN, "build", "-q", "-j", threads, path], before=clean,
                after=lambda: {"output_bytes": du(out)}), out


def zarr_floor(work, label, root, out):
    """The I/O floor of a zarr source: `cat` of every file of the store, then the outputs."""
    return io_floor(work, label, root, out,
                    files=sorted(str(p) for p in (root / "replay.zarr").rglob("*") if p.is_file()))


def zarr_numpy(work, label, root):
    out = work / "runs" / label

    def after():
        size = du(out)
        shutil.rmtree(out)
        return {"output_bytes": size}

    return Case(label, [PY, REPO / "bench" / "numpy_pipeline.py", root / "replay.zarr", out,
                        "--chunk", 100, "--fps", 50, "--zarr"],
                env={"OMP_NUM_THREADS": "1"},
                before=lambda: shutil.rmtree(out, ignore_errors=True), after=after)


def linked(src_root, dest, count, repeat=1):
    """A source directory of symlinks: the first `count` episodes, `repeat` times over (as new
    episode numbers)."""
    episodes = dest / "episodes"
    if episodes.exists():
        shutil.rmtree(episodes)
    episodes.mkdir(parents=True)
    for r in range(repeat):
        for e in range(count):
            (episodes / f"episode_{r * count + e}.hdf5").symlink_to(
                src_root / "episodes" / f"episode_{e}.hdf5")
    return dest


def spec(root, cameras, profiles, out):
    chans = "".join(f'"observation.cam{c}" = "observations/images/cam{c}"\n' for c in range(cameras))
    text = (f'version = 1\n[source]\nformat = "aloha_hdf5"\npath = "{root / "episodes"}"\n'
            f'fps = 50\n[source.channels]\naction = "action"\n'
            f'"observation.state" = "observations/qpos"\n{chans}'
            f'[split]\nval_fraction = 0.1\nseed = 0\n[output]\ndir = "{out}"\n{profiles}')
    path = out.parent / f"{out.name}.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


class Case:
    """One measurement of an interleaved group: a command, what runs untimed before it, and
    what is kept of its result."""

    def __init__(self, label, cmd, env=None, before=None, after=None):
        self.label, self.cmd, self.env = label, cmd, env
        self.before, self.after = before, after
        self.runs = []


def interleaved(cases):
    """Runs every case once per round, REPEAT rounds; returns label -> the run with the median
    wall time (median samples/s when the command prints it), with every run's number in round
    order (`walls_s`, and `all_samples_per_s`)."""
    for _ in range(REPEAT):
        for c in cases:
            log(f"  {c.label}")
            if c.before:
                c.before()
            r = timed_once(c.cmd, c.env)
            out = r.pop("stdout").strip()
            if out.startswith("{") or "\n{" in out:
                r.update(json.loads(out.splitlines()[-1]))
            if c.after:
                r.update(c.after() or {})
            c.runs.append(r)
    results = {}
    for c in cases:
        key = (lambda r: r["samples_per_s"]) if "samples_per_s" in c.runs[0] else (
            lambda r: r["wall_s"])
        median = dict(sorted(c.runs, key=key)[len(c.runs) // 2])
        median["walls_s"] = [r["wall_s"] for r in c.runs]
        if "samples_per_s" in c.runs[0]:
            median["all_samples_per_s"] = [round(r["samples_per_s"]) for r in c.runs]
        results[c.label] = median
    return results, {c.label: c.runs for c in cases}


def chunkc(work, label, root, cameras, profiles=ONE, threads=2):
    """A chunkc build; its output stays until the case runs again (the I/O floor reads it)."""
    out = work / "runs" / label
    path = spec(root, cameras, profiles, out)
    lock = out.parent / "chunkc.lock"

    def clean():
        shutil.rmtree(out, ignore_errors=True)
        lock.unlink(missing_ok=True)

    clean()
    return Case(label, [BIN, "build", "-q", "-j", threads, path], before=clean,
                after=lambda: {"output_bytes": du(out)}), out


def twin_builds(work, root):
    """Two independent 1-thread builds of the same spec at once (their own output and lock
    directories): what this machine gives two threads with nothing at all shared between them,
    the ceiling for `-j 2` against `-j 1`."""
    outs = [work / "runs" / "lowdim_twin_a", work / "runs-twin" / "lowdim_twin_b"]
    specs = [spec(root, 0, ONE, out) for out in outs]

    def clean():
        for out in outs:
            shutil.rmtree(out, ignore_errors=True)
            (out.parent / "chunkc.lock").unlink(missing_ok=True)

    script = '"$1" build -q -j 1 "$2" & first=$!; "$1" build -q -j 1 "$3" && wait $first'
    return Case("lowdim_twin_1thread", ["bash", "-c", script, "twin", BIN, *specs],
                before=clean, after=clean)


def zarr_twin(work, label, root):
    """[`twin_builds`] for a zarr replay buffer with the DEFAULT spec: two independent 1-thread
    builds at once, the machine's own ceiling for `-j 2` against `-j 1`."""
    outs = [work / "runs" / f"{label}_a", work / "runs-twin" / f"{label}_b"]
    specs = [zarr_spec(root, out) for out in outs]

    def clean():
        for out in outs:
            shutil.rmtree(out, ignore_errors=True)
            (out.parent / "chunkc.lock").unlink(missing_ok=True)

    script = '"$1" build -q -j 1 "$2" & first=$!; "$1" build -q -j 1 "$3" && wait $first'
    return Case(label, ["bash", "-c", script, "twin", BIN, *specs], before=clean, after=clean)


def io_floor(work, label, root, out, files=None):
    """`cat` of the source files (`files`, by default the episode files under `root`), then of the
    outputs in `out` (as the last build left them) into one file with `dd conv=fsync`."""
    if files is None:
        files = sorted(str(p) for p in (root / "episodes").iterdir())
    copy = work / "runs" / "floor.bin"
    script = ('xargs -0 cat < "$1" > /dev/null && xargs -0 cat < "$2" | '
              'dd of="$3" bs=4M conv=fsync status=none')
    src_list, out_list = work / "runs" / f"{label}-src.lst", work / "runs" / f"{label}-out.lst"
    src_list.write_text("\0".join(files))

    def before():
        out_list.write_text("\0".join(sorted(str(p) for p in out.rglob("*") if p.is_file())))

    def after():
        written = copy.stat().st_size
        copy.unlink()
        return {"read_bytes": sum(os.path.getsize(f) for f in files), "write_bytes": written}

    return Case(label, ["bash", "-c", script, "floor", src_list, out_list, copy], before=before,
                after=after)


def numpy_pipeline(work, label, root, cameras):
    out = work / "runs" / label
    cams = ",".join(f"cam{c}" for c in range(cameras))

    def after():
        size = du(out)
        shutil.rmtree(out)
        return {"output_bytes": size}

    return Case(label, [PY, REPO / "bench" / "numpy_pipeline.py", root / "episodes", out,
                        "--chunk", 100, "--fps", 50, "--cameras", cams],
                env={"OMP_NUM_THREADS": "1"},
                before=lambda: shutil.rmtree(out, ignore_errors=True), after=after)


def warm(root):
    """Reads the source once so every measurement sees the same (warm) page cache."""
    subprocess.run(["bash", "-c", f'cat "{root}"/episodes/* > /dev/null'], check=True)


def loader(mode, profile, source, workers, samples):
    return Case(f"loader_{mode}_w{workers}",
                [PY, REPO / "bench" / "loader_bench.py", mode, profile, source / "episodes",
                 "--workers", workers, "--samples", samples])


def paired(rounds, a, b, field="wall_s"):
    """The median over rounds of a's value / b's value in the same round."""
    if a not in rounds or b not in rounds:
        return None
    values = sorted(x[field] / y[field] for x, y in zip(rounds[a], rounds[b]) if y[field])
    return round(values[len(values) // 2], 3) if values else None


def machine():
    load = Path("/proc/loadavg").read_text().split()[:3]
    return {"cpus": os.cpu_count(), "platform": platform.platform(),
            "loadavg_1_5_15": [float(x) for x in load],
            "chunkc": subprocess.run([str(BIN), "--version"], capture_output=True,
                                     text=True).stdout.strip()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, for a smoke run")
    ap.add_argument("--work", type=Path, default=Path("/tmp/chunkc-bench"))
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results.json")
    ap.add_argument("--only", choices=["lowdim", "images", "loader", "zarr"], action="append",
                    help="measurement groups (default: lowdim, images, loader; zarr only when "
                    "asked for)")
    ap.add_argument("--clean", action="store_true", help="delete WORK when done")
    ap.add_argument("--repeat", type=int, default=5,
                    help="rounds of every measurement; medians are reported (default 5)")
    args = ap.parse_args()
    if not BIN.exists():
        raise SystemExit(f"{BIN} not found: run `cargo build --release` first")
    global REPEAT
    REPEAT = max(1, args.repeat)
    size = SIZES["quick" if args.quick else "full"]
    work = args.work.resolve()
    (work / "runs").mkdir(parents=True, exist_ok=True)
    parts = set(args.only or ["lowdim", "images", "loader"])
    res = {"size": "quick" if args.quick else "full", "sizes": size, "dims": DIMS,
           "cache": "warm (sources read once before timing; drop_caches not used)",
           "machine_before": machine(), "runs": {}}
    runs = res["runs"]
    started = time.time()

    rounds = {}

    def measure(cases):
        results, per_round = interleaved(cases)
        runs.update(results)
        rounds.update(per_round)

    if "lowdim" in parts:
        n = size["lowdim"]["episodes"]
        low = synth(work, "lowdim", cameras=0, **size["lowdim"])
        low2 = linked(low, work / "data" / f"lowdim-2N-{low.name}", n, repeat=2)
        warm(low)
        one, out = chunkc(work, "lowdim_1p", low, 0)
        log("low-dim, interleaved")
        measure([numpy_pipeline(work, "lowdim_numpy", low, 0), one,
                 io_floor(work, "lowdim_floor", low, out),
                 chunkc(work, "lowdim_1p_1thread", low, 0, threads=1)[0],
                 twin_builds(work, low),
                 chunkc(work, "lowdim_4p", low, 0, profiles=FOUR)[0],
                 chunkc(work, "lowdim_1p_2N", low2, 0)[0]])
        for label in ("lowdim_1p", "lowdim_1p_1thread", "lowdim_4p", "lowdim_1p_2N"):
            shutil.rmtree(work / "runs" / label, ignore_errors=True)
    if "zarr" in parts:
        n, steps = size["lowdim"]["episodes"], size["lowdim"]["steps"]
        for layout in ZARR_LAYOUTS:
            root = synth_zarr(work, layout, n, steps)
            half = synth_zarr(work, layout, n // 2, steps)
            subprocess.run(["bash", "-c", f'find "{root}" "{half}" -type f -exec cat {{}} + '
                            '> /dev/null'], check=True)
            one, out = zarr_chunkc(work, f"zarr_{layout}_1p", root)
            log(f"zarr {layout}, interleaved")
            group = [zarr_numpy(work, f"zarr_{layout}_numpy", root), one,
                     zarr_floor(work, f"zarr_{layout}_floor", root, out),
                     zarr_chunkc(work, f"zarr_{layout}_1p_half", half)[0],
                     zarr_chunkc(work, f"zarr_{layout}_nodoctor", root, doctor=False)[0]]
            if layout == "episode":
                group.append(zarr_chunkc(work, f"zarr_{layout}_1p_1thread", root, threads=1)[0])
                group.append(zarr_chunkc(work, f"zarr_{layout}_nodoctor_1thread", root,
                                         doctor=False, threads=1)[0])
                group.append(zarr_twin(work, f"zarr_{layout}_twin_1thread", root))
            measure(group)
            for label in (f"zarr_{layout}_1p", f"zarr_{layout}_1p_half",
                          f"zarr_{layout}_nodoctor", f"zarr_{layout}_1p_1thread",
                          f"zarr_{layout}_nodoctor_1thread"):
                shutil.rmtree(work / "runs" / label, ignore_errors=True)
    if "images" in parts:
        n = size["images"]["episodes"]
        img = synth(work, "images", cameras=2, **size["images"])
        half = linked(img, work / "data" / f"images-half-{img.name}", n // 2)
        warm(img)
        one, out = chunkc(work, "images_1p", img, 2)
        log("images, interleaved")
        measure([numpy_pipeline(work, "images_numpy", img, 2), one,
                 io_floor(work, "images_floor", img, out),
                 chunkc(work, "images_1p_half", half, 2)[0]])
        for label in ("images_1p", "images_1p_half"):
            shutil.rmtree(work / "runs" / label, ignore_errors=True)
    if "loader" in parts:
        n = size["images"]["episodes"]
        img = synth(work, "images", cameras=2, **size["images"])
        sub = linked(img, work / "data" / "loader-source", min(n, size["loader_episodes"]))
        build, out = chunkc(work, "loader", sub, 2)
        log("building the loader's dataset")
        subprocess.run([str(c) for c in build.cmd], check=True)
        profile = out / "act"
        samples = size["loader_samples"]
        log("loader, interleaved")
        measure([loader(mode, profile, sub, workers, samples)
                 for mode, workers in (("chunkc", 0), ("act", 0), ("chunkc", 2), ("act", 2),
                                       ("chunkc_mem", 0), ("numpy_mem", 0))])
        shutil.rmtree(out)

    for r in runs.values():
        r.pop("stdout", None)
    rows = []

    def row(name, value, target, ok):
        rows.append({"ratio": name, "value": value, "target": target,
                     "met": None if value is None else ok(value)})

    pair = lambda a, b, f="wall_s": paired(rounds, a, b, f)  # noqa: E731
    peak = lambda k: round(max(r["peak_rss_mib"] for r in rounds[k]), 1)  # noqa: E731
    if "lowdim" in parts:
        row("low-dim: numpy pipeline / chunkc (wall)", pair("lowdim_numpy", "lowdim_1p"),
            ">= 3", lambda v: v >= 3)
        row("low-dim: chunkc / I/O floor (wall)", pair("lowdim_1p", "lowdim_floor"),
            "<= 3", lambda v: v <= 3)
        row("low-dim: 4 profiles / 1 profile (wall)", pair("lowdim_4p", "lowdim_1p"),
            "<= 1.5", lambda v: v <= 1.5)
        row("low-dim: 1 thread / 2 threads (wall)", pair("lowdim_1p_1thread", "lowdim_1p"),
            ">= 1.7", lambda v: v >= 1.7)
        twin = paired(rounds, "lowdim_1p_1thread", "lowdim_twin_1thread")
        row("low-dim: machine's ceiling, 2 x 1-thread / two 1-thread builds at once",
            None if twin is None else round(2 * twin, 3), "(reference)", lambda v: None)
        row("low-dim: peak RSS 2N / N", pair("lowdim_1p_2N", "lowdim_1p", "peak_rss_mib"),
            "<= 1.1", lambda v: v <= 1.1)
        row("low-dim: peak RSS MiB (2N, largest run)", peak("lowdim_1p_2N"), "< 512",
            lambda v: v < 512)
    if "zarr" in parts:
        for layout in ZARR_LAYOUTS:
            z = f"zarr_{layout}"
            floor_target = 1.5 if layout == "episode" else 2
            row(f"zarr {layout}: numpy pipeline / chunkc (wall)",
                pair(f"{z}_numpy", f"{z}_1p"), ">= 2.5", lambda v: v >= 2.5)
            row(f"zarr {layout}: chunkc / I/O floor (wall)", pair(f"{z}_1p", f"{z}_floor"),
                f"<= {floor_target}", lambda v, t=floor_target: v <= t)
            row(f"zarr {layout}: peak RSS N / (N/2)",
                pair(f"{z}_1p", f"{z}_1p_half", "peak_rss_mib"), "<= 1.1", lambda v: v <= 1.1)
            row(f"zarr {layout}: peak RSS MiB (N, largest run)", peak(f"{z}_1p"), "< 512",
                lambda v: v < 512)
            row(f"zarr {layout}: default spec / doctor off (wall)",
                pair(f"{z}_1p", f"{z}_nodoctor"), "<= 1.15", lambda v: v <= 1.15)
            row(f"zarr {layout}: numpy pipeline / chunkc doctor off (wall)",
                pair(f"{z}_numpy", f"{z}_nodoctor"), "(reference)", lambda v: None)
            if layout == "episode":
                twin = pair(f"{z}_1p_1thread", f"{z}_twin_1thread")
                ceiling = None if twin is None else round(2 * twin, 3)
                row(f"zarr {layout}: machine's ceiling, 2 x 1-thread / two 1-thread builds at "
                    "once", ceiling, "(reference)", lambda v: None)
                row(f"zarr {layout}: 1 thread / 2 threads, default spec (wall)",
                    pair(f"{z}_1p_1thread", f"{z}_1p"),
                    ">= the machine's ceiling" if ceiling else ">= 1.7",
                    lambda v, c=ceiling: v >= (c if c else 1.7))
                row(f"zarr {layout}: 1 thread / 2 threads, doctor off (wall)",
                    pair(f"{z}_nodoctor_1thread", f"{z}_nodoctor"), "(reference)",
                    lambda v: None)
    if "images" in parts:
        row("images: numpy pipeline / chunkc (wall)", pair("images_numpy", "images_1p"),
            ">= 2", lambda v: v >= 2)
        row("images: chunkc / I/O floor (wall)", pair("images_1p", "images_floor"),
            "<= 2", lambda v: v <= 2)
        row("images: peak RSS N / (N/2)", pair("images_1p", "images_1p_half", "peak_rss_mib"),
            "<= 1.1", lambda v: v <= 1.1)
        row("images: peak RSS MiB (N, largest run)", peak("images_1p"), "< 512",
            lambda v: v < 512)
    if "loader" in parts:
        for w in (0, 2):
            row(f"loader: chunkc / open-per-item, {w} workers (samples/s)",
                pair(f"loader_chunkc_w{w}", f"loader_act_w{w}", "samples_per_s"), ">= 3",
                lambda v: v >= 3)
        row("loader: numpy in-memory / chunkc in_memory (samples/s)",
            pair("loader_numpy_mem_w0", "loader_chunkc_mem_w0", "samples_per_s"), "<= 1.5",
            lambda v: v <= 1.5)
    res["table"] = rows
    res["machine_after"] = machine()
    res["total_s"] = round(time.time() - started, 1)
    args.out.write_text(json.dumps(res, indent=2) + "\n")

    print(f"\n{'measurement':34} {'wall s':>8} {'cpu s':>8} {'RSS MiB':>8}")
    for k, r in runs.items():
        extra = f"  {r['samples_per_s']:.0f} samples/s" if "samples_per_s" in r else ""
        print(f"{k:34} {r['wall_s']:8.2f} {r['cpu_s']:8.2f} {r['peak_rss_mib']:8.1f}{extra}")
    print(f"\n{'ratio':58} {'value':>8}  {'target':>7}  met")
    for r in rows:
        print(f"{r['ratio']:58} {r['value']!s:>8}  {r['target']:>7}  {r['met']}")
    print(f"\nload average before {res['machine_before']['loadavg_1_5_15']}, "
          f"after {res['machine_after']['loadavg_1_5_15']}; written to {args.out}")
    if args.clean:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()
