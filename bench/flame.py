"""A flame graph of a profiled run, drawn with matplotlib from `perf script` output: where the
CPU time of a build goes, for book/src/performance.md. A note, not a test.

    perf record --call-graph dwarf,8192 -F 2000 -o /tmp/perf.data \\
        target/release/chunkc build -q -j 2 SPEC
    perf script -i /tmp/perf.data | .venv/bin/python bench/flame.py -o OUT.png \\
        [--title TEXT] [--fold OUT.folded]

Each sample's stack runs from the root (bottom) to the function on the CPU (top); a box's width
is its share of all samples (both threads' CPU time, not wall time). Thread-pool and closure
plumbing (rayon, std's runtime, `FnOnce` shims) is dropped so that the build's own functions sit
on each other; Rust's hashes and generic arguments are cut from the names. Boxes are coloured by
what the stack is doing: the dataset doctor, hashing, HDF5, statistics, the kernel, the rest.
`--fold` also writes the folded stacks (`root;...;leaf count`, the format of Brendan Gregg's
flamegraph.pl and inferno) for any other viewer.
"""

import argparse
import re
import sys
from collections import Counter

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402

# Frames that are only the machinery between the build's functions.
PLUMBING = re.compile(
    r"^(rayon_core::|rayon::iter::plumbing|rayon::iter::|rayon::slice::|std::rt::|std::sys::|"
    r"std::panicking|std::panic::|core::ops::function|std::thread::|crossbeam|__rust_|"
    r"core::panic|<alloc::boxed::Box|alloc::boxed::|std::sys_common|_start$|__libc_start|"
    r"start_thread$|clone3?$|__clone|main$|std::rt|core::iter::|<core::iter|"
    r"<rayon|<core::|<alloc::|alloc::vec::|core::slice::iter|std::sys::backtrace|"
    r"std::thread::|<std::thread|<std::sys::)")
# (label, colour, what a stack's names contain), first match wins; the last takes the rest.
CATEGORIES = [("dataset doctor", "#d95f5f", ("doctor",)), ("hashing", "#9d7ad2", ("blake3", "hash")),
              ("HDF5", "#5f8fd9", ("hdf5", "H5")), ("statistics", "#5fb86a", ("stats",)),
              ("kernel", "#b0b0b0", ("[k]",)), ("the rest", "#e8a33d", ("",))]


def clean(sym: str, dso: str):
    """The frame's name without hash, offset and generic arguments, its last three path
    segments; None for plumbing."""
    sym = re.sub(r"\+0x[0-9a-f]+$", "", sym)
    sym = re.sub(r"::h[0-9a-f]{16}$", "", sym)
    if PLUMBING.match(sym):
        return None
    for _ in range(6):
        sym = re.sub(r"<[^<>]*>", "", sym)
    sym = sym.replace("{{closure}}", "{closure}").replace("{{vtable.shim}}", "")
    if "kernel" in dso:
        return f"[k] {sym}"
    parts = [p for p in sym.split("::") if p and p != "{closure}"]
    return "::".join(parts[-3:]) if parts else sym


def stacks(lines):
    """Each sample's frames, root first."""
    frames = []
    for line in lines:
        line = line.rstrip("\n")
        if not line.strip():
            if frames:
                yield frames[::-1]
            frames = []
            continue
        if not line.startswith(("\t", " ")):
            continue
        m = re.match(r"\s*[0-9a-f]+\s+(.*?)\s+\((.*)\)$", line)
        if not m:
            continue
        sym, dso = m.groups()
        name = None if sym == "[unknown]" else clean(sym, dso)
        if name:
            frames.append(name)
    if frames:
        yield frames[::-1]


def fold(samples):
    counts = Counter()
    for frames in samples:
        kept = []
        for f in frames:
            if kept and kept[-1] == f:
                continue
            kept.append(f)
        counts[";".join(kept) or "[unknown]"] += 1
    return counts


def category(text):
    """The (label, colour) of a stack given as its names joined."""
    return next((label, c) for label, c, keys in CATEGORIES if any(k in text for k in keys))


def draw(counts, out, title, depth_cap=24, least=0.004):
    total = sum(counts.values())
    tree = {}
    for stack, n in counts.items():
        node = tree
        for f in stack.split(";")[:depth_cap]:
            entry = node.setdefault(f, [0, {}])
            entry[0] += n
            node = entry[1]
    boxes = []

    def place(node, x, depth, path):
        for name, (n, children) in sorted(node.items(), key=lambda kv: -kv[1][0]):
            w = n / total
            if w >= least:
                boxes.append((x, depth, w, name, path + [name]))
                place(children, x, depth + 1, path + [name])
            x += w

    place(tree, 0.0, 0, [])
    depth = 1 + max(d for _, d, *_ in boxes)
    fig, ax = plt.subplots(figsize=(15, 0.32 * depth + 1.2))
    for x, d, w, name, path in boxes:
        ax.add_patch(Rectangle((x, d), w, 0.92, facecolor=category(";".join(path))[1], edgecolor="white",
                               linewidth=0.4))
        # About 4.3 points a character: the longest label that fits, down to the function.
        chars = int(w * 15 * 72 / 4.3)
        parts = name.split("::")
        fits = [t for t in (f"{'::'.join(parts[-2:])} {100 * w:.0f}%",
                            f"{parts[-1]} {100 * w:.0f}%", parts[-1]) if len(t) <= chars]
        if fits:
            ax.text(x + 0.002, d + 0.45, fits[0], va="center", fontsize=6.5, family="monospace")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, depth)
    ax.set_yticks([])
    ax.set_xlabel(f"share of the CPU samples ({total} samples, both threads)")
    ax.set_title(title, fontsize=10)
    handles = [Rectangle((0, 0), 1, 1, facecolor=c) for _, c, _ in CATEGORIES]
    ax.legend(handles, [label for label, _, _ in CATEGORIES], loc="upper right", fontsize=7,
              ncol=len(CATEGORIES), frameon=False, bbox_to_anchor=(1, 1.0))
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("-o", "--out", required=True)
    ap.add_argument("--title", default="chunkc build: where the CPU time goes")
    ap.add_argument("--fold")
    args = ap.parse_args()
    counts = fold(stacks(sys.stdin))
    if not counts:
        raise SystemExit("no samples on stdin: pipe `perf script` output in")
    if args.fold:
        with open(args.fold, "w") as f:
            for stack, n in sorted(counts.items()):
                f.write(f"{stack} {n}\n")
    draw(counts, args.out, args.title)
    total = sum(counts.values())
    share = Counter()
    for stack, n in counts.items():
        share[category(stack)[0]] += n
    print(", ".join(f"{k} {100 * n / total:.1f}%" for k, n in share.most_common()))


if __name__ == "__main__":
    main()
