"""The book's frame-storage charts from bench/results-frame-storage.json (written by
bench/frame_storage.py): output size against loader samples/s, per storage, beside
LeRobotDataset's two backends; and, from bench/results-frame-storage-real.json (its real-video
case), samples/s of chunkc's loader, the decode floor and LeRobotDataset per codec and window.

    .venv/bin/python bench/plot_frame_storage.py [RESULTS] [OUT.png]
    .venv/bin/python bench/plot_frame_storage.py --real [RESULTS] [OUT.png]
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


def real(args):
    results = Path(args[0]) if args else REPO / "bench" / "results-frame-storage-real.json"
    out = Path(args[1]) if len(args) > 1 else REPO / "book" / "src" / "images" / "frame-storage-real.png"
    r = json.loads(results.read_text())
    readers = [("chunkc loader", "chunkc", "#48c"), ("decode floor", "floor", "#888"),
               ("LeRobotDataset torchcodec", "lerobot_torchcodec", "#c84"),
               ("LeRobotDataset pyav", "lerobot_pyav", "#d9a")]
    cases = list(r["loaders"])
    fig, ax = plt.subplots(figsize=(10, 3.8))
    width = 0.8 / len(readers)
    for k, (name, key, color) in enumerate(readers):
        xs = [i + (k - (len(readers) - 1) / 2) * width for i in range(len(cases))]
        values = [r["loaders"][c].get(key, 0.0) for c in cases]
        ax.bar(xs, values, width=width, label=name, color=color)
        if key == "chunkc":
            for x, v, c in zip(xs, values, cases):
                ratio = r["loaders"][c].get("chunkc_vs_best_lerobot")
                ax.text(x, v, f"{r['loaders'][c]['chunkc_vs_floor']:.2f}x floor\n{ratio}x LeRobot",
                        ha="center", va="bottom", fontsize=6)
    labels = [f"{c.split('/')[0]} ({r['sources'][c.split('/')[0]]['keyframe_spacing']:g}-frame GOP)\n"
              f"{c.split('/')[1].replace('_', ' ')}" for c in cases]
    ax.set_xticks(range(len(cases)), labels, fontsize=7)
    ax.set_ylabel(f"samples/s, {r['workers']} workers, median of {r['rounds']}")
    ax.legend(fontsize=7)
    ax.set_title(f"{r['footage']}: one 640x480 camera at 30 fps; batch {r['batch']}, shuffled", fontsize=9)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(out)


def main():
    if sys.argv[1:2] == ["--real"]:
        return real(sys.argv[2:])
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "bench" / "results-frame-storage.json"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else REPO / "book" / "src" / "images" / "frame-storage.png"
    r = json.loads(results.read_text())
    fig, (size_ax, speed_ax) = plt.subplots(1, 2, figsize=(10, 3.8))
    storages = [s for s in ["none", "jpeg", "video", "video_encoded"] if s in r["builds"]]
    mb = [r["builds"][s]["bytes"]["act"] / 1e6 for s in storages]
    labels = [f"chunkc {s.replace('_', ' ')}" for s in storages] + ["source mp4s"]
    colors = ["#888", "#4a8", "#48c", "#7ad", "#c84"][-len(labels):]
    size_ax.barh(labels, mb + [r["source_video_bytes"] / 1e6], color=colors)
    size_ax.set_xscale("log")
    size_ax.set_xlabel("bytes on disk, MB (log)")
    size_ax.set_title("output size (one profile)")
    for y, v in enumerate(mb + [r["source_video_bytes"] / 1e6]):
        size_ax.text(v, y, f" {v:.2f}", va="center", fontsize=8)
    readers = [(f"chunkc {s.replace('_', ' ')}", f"chunkc_{s}") for s in storages]
    readers += [("LeRobotDataset torchcodec", "lerobot_torchcodec"), ("LeRobotDataset pyav", "lerobot_pyav")]
    width = 0.38
    for k, (preset, shift) in enumerate([("act", -width / 2), ("diffusion_policy", width / 2)]):
        values = [r["loaders"][preset][key] for _, key in readers]
        speed_ax.barh([y + shift for y in range(len(readers))], values, height=width,
                      label=preset.replace("_", " "))
    speed_ax.set_yticks(range(len(readers)), [name for name, _ in readers])
    speed_ax.set_xscale("log")
    speed_ax.set_xlabel(f"samples/s (log), {r['workers']} workers, median of {r.get('rounds', 1)}")
    speed_ax.set_title("loader throughput")
    speed_ax.legend(fontsize=8)
    fig.suptitle(f"{r['episodes']} episodes x {r['frames_per_episode']} frames, {r['cameras']} cameras "
                 f"{r['resolution']}, source {r['source']}", fontsize=9)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
