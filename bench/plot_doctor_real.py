"""Draws what the doctor flags on a real dataset (book/src/images/doctor-real-flags.png): for each
`jump` and `frozen` finding of `chunkc audit`'s audit.json, the flagged action dimension around
the finding, beside the same dimension in a few unflagged episodes.

    .venv/bin/python bench/plot_doctor_real.py DATASET AUDIT_JSON OUT_PNG
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import doctor_real  # noqa: E402


def main(dataset, audit_json, out):
    dataset = Path(dataset)
    info = json.loads((dataset / "meta" / "info.json").read_text())
    action_key, _ = doctor_real.keys(info)
    eps = doctor_real.load(dataset, action_key)
    audit = json.loads(Path(audit_json).read_text())
    found = [(e["id"], f) for e in audit["episodes"] for f in e.get("findings", [])
             if f["flag"] in ("jump", "frozen")]
    fig, axes = plt.subplots(len(found), 1, figsize=(9, 1.9 * len(found)), squeeze=False)
    for ax, (ep, f) in zip(axes[:, 0], found):
        d = int(f["evidence"]["dim"])
        x = eps[ep][:, d]
        if f["flag"] == "jump":
            t = int(f["evidence"]["step"])
            lo, hi = max(0, t - 30), min(len(x), t + 31)
            ax.plot(range(lo, hi), x[lo:hi], ".-", lw=1)
            ax.axvline(t, color="red", lw=0.8)
        else:
            ax.plot(x, lw=1)
            s, n = int(f["evidence"]["from"]), int(f["evidence"]["steps"])
            ax.axvspan(s, s + n, color="red", alpha=0.15)
        ax.set_title(f"episode {ep}, action[{d}]: {f['flag']}: {f['detail'][:110]}", fontsize=7)
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=90)


if __name__ == "__main__":
    main(*sys.argv[1:4])
