#!/usr/bin/env python3
"""Build a chunkc spec as N shards on Ray, then merge them into the single-machine outputs.

    python scripts/chunkc_ray.py SPEC --num-shards N [--address ray://head:10001] [--partials DIR]

Each shard is one Ray task running `chunkc build SPEC --shard I/N --partials DIR`; the driver
then runs `chunkc merge SPEC --partials DIR` (the outputs are byte-identical to `chunkc build
SPEC`). The spec, its source, the partials directory and the output directory must be on a
filesystem every worker sees at the same path, and `chunkc` on every worker's PATH (or
`--chunkc`). A task that fails (a non-zero exit, a killed worker or node) is retried up to
`--max-retries` times; a retried shard writes the same partial.

Without `--address` Ray starts on this machine (`--num-cpus` caps it): the tests run it so.
"""

import argparse
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path


def parse(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("spec", type=Path)
    p.add_argument("--num-shards", type=int, required=True, help="N: how many shard tasks")
    p.add_argument("--partials", type=Path, default=None,
                   help="shared directory for the partials (default: <spec dir>/.chunkc-partials/<spec name>)")
    p.add_argument("--address", default=None, help="an existing Ray cluster (default: start one here)")
    p.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local Ray (without --address)")
    p.add_argument("--threads-per-shard", type=int, default=1,
                   help="chunkc -j of each shard, and the CPUs each task asks Ray for")
    p.add_argument("--max-retries", type=int, default=3)
    p.add_argument("--chunkc", default=os.environ.get("CHUNKC_BIN", "chunkc"))
    p.add_argument("--keep-partials", action="store_true", help="leave the partials after the merge")
    args = p.parse_args(argv)
    if args.num_shards < 1:
        p.error("--num-shards must be at least 1")
    args.spec = args.spec.resolve()
    if args.partials is None:
        args.partials = args.spec.parent / ".chunkc-partials" / args.spec.stem
    args.partials = args.partials.resolve()
    return args


def run_shard(chunkc, spec, partials, index, count, threads):
    """One shard, as a Ray task body: runs chunkc and raises on failure (so Ray retries it)."""
    cmd = [chunkc, "-j", str(threads), "build", "-q", "--shard", f"{index}/{count}",
           "--partials", str(partials), str(spec)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    kill = os.environ.get("CHUNKC_RAY_TEST_KILL")  # test hook: "INDEX:MARKER_FILE"
    if kill:
        which, marker = kill.split(":", 1)
        if int(which) == index and not os.path.exists(marker):
            Path(marker).write_text("killed once\n")
            time.sleep(0.2)
            proc.kill()  # the shard dies mid-run, and so does its worker
            proc.wait()
            os._exit(1)
    out, err = proc.communicate()
    if proc.returncode != 0:
        raise RuntimeError(f"shard {index}/{count} failed ({proc.returncode}): {shlex.join(cmd)}\n{err}")
    return index, err.strip()


def main(argv=None):
    args = parse(argv)
    import ray

    n = args.num_shards
    args.partials.mkdir(parents=True, exist_ok=True)
    for old in args.partials.glob("shard-*-of-*.partial"):
        if not old.name.endswith(f"-of-{n:05d}.partial"):
            old.unlink()  # another run's N: the merge would refuse the mix
    if args.address:
        ray.init(address=args.address)
    else:
        ray.init(num_cpus=args.num_cpus, include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=args.threads_per_shard, max_retries=args.max_retries,
                      retry_exceptions=True)(run_shard)
    start = time.time()
    pending = [task.remote(args.chunkc, args.spec, args.partials, i, n, args.threads_per_shard)
               for i in range(n)]
    done = 0
    try:
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            index, said = ray.get(ready[0])
            done += 1
            print(f"[{done}/{n}] shard {index} done after {time.time() - start:.1f} s: {said}",
                  file=sys.stderr, flush=True)
    except Exception as e:  # a shard that failed every retry
        print(f"chunkc_ray: {e}", file=sys.stderr)
        return 1
    finally:
        ray.shutdown()
    merge = subprocess.run([args.chunkc, "merge", "-q", "--partials", str(args.partials), str(args.spec)],
                           capture_output=True, text=True)
    sys.stderr.write(merge.stderr)
    if merge.returncode != 0:
        return merge.returncode
    print(f"chunkc_ray: {n} shards and the merge in {time.time() - start:.1f} s", file=sys.stderr)
    if not args.keep_partials:
        for part in args.partials.glob("shard-*-of-*.partial"):
            part.unlink()
    return 0


if __name__ == "__main__":
    sys.exit(main())
