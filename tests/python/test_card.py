"""The dataset card (README.md) tells what the build did (issue 37): the audit's verdicts, the
episodes left out with their reasons, the dataset doctor's findings by check (how many episodes
and which), and the storage (format, image_compression, codec, whether the video was copied).

The oracles are independent of the card's code: `chunkc audit`'s audit.json (the verdicts and
each episode's flags), meta.json's `excluded`, the data file's `/videos/<camera>/copied`, and
the faults `chunkc synth` planted (faults.json)."""

import json
import re
import shutil

import h5py

from conftest import REPO, build_with_video, run_chunkc

V21 = REPO / "tests" / "data" / "lerobot_video_v21"
TOP = "observation.images.top"


def section(card: str, title: str) -> str:
    """The text of `## title` up to the next `## `."""
    start = card.index(f"## {title}\n")
    end = card.find("\n## ", start + 1)
    return card[start:end if end > 0 else len(card)]


def table(text: str, header: str) -> dict:
    """Rows of the markdown table whose header starts with `| header |`, by first cell."""
    lines = text.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith(f"| {header} |"))
    rows = {}
    for line in lines[at + 2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split(" | ")]
        rows[cells[0].strip("`")] = cells[1:]
    return rows


def test_card_states_a_missing_video_and_the_copies(tmp_path):
    source = tmp_path / "src"
    shutil.copytree(V21, source)
    missing = source / "videos" / "chunk-000" / TOP / "episode_000001.mp4"
    missing.unlink()
    spec = tmp_path / "spec.toml"
    spec.write_text("\n".join([
        "version = 1", "[source]", 'format = "lerobot"', f'path = "{source}"', "[source.channels]",
        'action = "action"', '"observation.state" = "observation.state"', f'"{TOP}" = "{TOP}"',
        "[split]", "val_fraction = 0.0", "[output]", 'dir = "out"',
        "[audit]", 'video = "exclude_episode"',
        "[profiles.video]", 'preset = "diffusion_policy"', "chunk = 4", 'image_compression = "video"',
    ]) + "\n")
    run_chunkc("audit", spec)
    audit = json.loads((tmp_path / "out" / "audit" / "audit.json").read_text())
    build_with_video(spec)
    root = tmp_path / "out" / "video"
    card = (root / "README.md").read_text()
    meta = json.loads((root / "meta.json").read_text())

    verdicts = section(card, "Audit")
    counts = {v: sum(e["verdict"] == v for e in audit["episodes"]) for v in ("ok", "interpolate", "resample", "exclude")}
    assert ", ".join(f"{n} {v}" for v, n in counts.items()) in verdicts, verdicts
    assert counts["exclude"] == 1
    # The timing flags by kind, and the excluded episode with the audit's reason.
    assert table(verdicts, "timing flag")["video"][:2] == ["1 of 3", "1"]
    excluded = table(verdicts, "episode")
    assert list(excluded) == [str(e["id"]) for e in meta["excluded"]] == ["1"]
    assert excluded["1"][0] == meta["excluded"][0]["reason"] and "missing" in excluded["1"][0]

    storage = section(card, "Storage")
    assert "Format `hdf5` (`data.h5`)" in storage and "image_compression `video`" in storage
    with h5py.File(root / "data.h5", "r") as f:
        copied = f[f"videos/{TOP}/copied"][:]
    assert len(copied) == 2 and copied.all()
    stored = table(storage, "camera")[TOP][0]
    assert "every episode's file (2) is the source's own" in stored and "copied" in stored, stored


def test_card_lists_the_doctors_findings_and_exclusions(tmp_path):
    out = tmp_path / "s"
    run_chunkc("synth", out, "--format", "diffusion-policy-zarr", "--episodes", 40, "--steps", 120,
               "--action-dim", 4, "--state-dim", 4, "--fps", 10, "--seed", 3,
               "--faults", "scale:100,frozen", "--fault-fraction", 0.1)
    spec = out / "spec.toml"
    spec.write_text(spec.read_text() + '\n[audit.doctor]\nunits = "exclude"\n')
    run_chunkc("audit", spec)
    audit = json.loads((out / "out" / "audit" / "audit.json").read_text())
    run_chunkc("build", "-q", spec)
    profile = next(p for p in (out / "out").iterdir() if (p / "README.md").exists())
    card = (profile / "README.md").read_text()
    meta = json.loads((profile / "meta.json").read_text())
    text = section(card, "Audit")

    # Each doctor flag the audit found: its episode count and ids.
    flagged = {}
    for e in audit["episodes"]:
        for f in e.get("findings", []):
            flagged.setdefault(f["flag"], set()).add(e["id"])
    assert "units" in flagged
    judged = sum(1 for e in audit["episodes"] if e["verdict"] != "exclude" or e.get("findings"))
    rows = table(text, "check")
    assert set(rows) == set(flagged), (rows, flagged)
    for flag, ids in flagged.items():
        count, which = rows[flag]
        assert count == f"{len(ids)} of {judged}"
        listed = [int(i) for i in re.findall(r"\d+", which.split(", and")[0])]
        assert listed == sorted(ids)[:20]
    # The episodes the doctor left out, each with its reason (meta.json's).
    excluded = table(text, "episode")
    assert {int(i): r[0] for i, r in excluded.items()} == {e["id"]: e["reason"] for e in meta["excluded"]}
    assert sorted(int(i) for i in excluded) == sorted(flagged["units"])
    assert all(r[0].startswith("dataset doctor: units") for r in excluded.values())
