"""The book's frame-storage chart from bench/results-frame-storage.json (written by
bench/frame_storage.py): output size against loader samples/s, per storage, beside
LeRobotDataset's two backends.

    .venv/bin/python bench/plot_frame_storage.py [RESULTS] [OUT.png]
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


def main():
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
