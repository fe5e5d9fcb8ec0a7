"""The dataset doctor inside `chunkc build`'s one pass (issue 30): the build computes the doctor's
features from the values it reads anyway (as it reads them, or from its row store beside the
writes) and judges them before anything is committed. The
oracle is `chunkc audit`, whose doctor reads the two channels in a pass of its own
(`read_lowdim`, not the build's `read_episode`): both must reach the same findings. The outputs'
bytes must not depend on the doctor when it only warns; its exclusions and errors must act as
they do in the audit, with nothing partial left behind."""

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest
import zarr

sys.path.insert(0, str(Path(__file__).resolve().parent))
from conftest import run_chunkc  # noqa: E402

FAULTS = "frozen,clip,jump,lag:3,delta,scale:10,duplicate"


def synth(tmp: Path, name: str, faults=FAULTS, episodes=80) -> Path:
    out = tmp / name
    run_chunkc("synth", out, "--format", "diffusion-policy-zarr", "--episodes", episodes,
               "--steps", 120, "--action-dim", 4, "--state-dim", 4, "--fps", 10, "--seed", 3,
               "--faults", faults, "--fault-fraction", 0.1)
    return out / "spec.toml"


def doctor_lines(text: str) -> list:
    lines = (l.strip().removeprefix("warning: ") for l in text.splitlines())
    return sorted(l for l in lines if l.startswith("dataset doctor: `"))


def scaled(spec: Path) -> list:
    """The episodes `chunkc synth` recorded in other units (faults.json: the generator's truth)."""
    faults = json.loads((spec.parent / "faults.json").read_text())["episodes"]
    return sorted(int(e) for e, fs in faults.items() if any(f["fault"] == "scale" for f in fs))


def hashes(directory: Path) -> dict:
    return {str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(directory.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("fps", [10.0, 5.0])
def test_build_finds_what_the_audit_finds(tmp_path, fps):
    """At the source's rate (10) the build reduces the episodes from its row store beside the
    writes; at 5 (every other step) no rate keeps the source's steps and the pass reduces each
    episode as it reads it. Both must find what the audit finds."""
    spec = synth(tmp_path, "s")
    spec.write_text(spec.read_text().replace("fps = 10.0\nformat", f"fps = {fps}\nformat"))
    assert f"fps = {fps}\nformat" in spec.read_text()
    audit_stderr = run_chunkc("audit", spec).stdout + run_chunkc("audit", spec).stderr
    audit = json.loads((spec.parent / "out" / "audit" / "audit.json").read_text())
    flagged = audit["doctor"]["flagged"]
    assert set(flagged) >= {"units", "jump", "duplicate"}, flagged
    # One line per flag, counting episodes of the episodes judged, listing them.
    n = len(audit["episodes"])
    expected = doctor_lines("\n".join(audit["warnings"]))
    assert len(expected) == len(flagged), expected
    for line, (flag, count) in zip(expected, sorted(flagged.items())):
        assert line.startswith(f"dataset doctor: `{flag}` in {count} of {n} episodes"), line
        ids = sorted(e["id"] for e in audit["episodes"] if flag in e["flags"])
        assert f"episodes {', '.join(map(str, ids[:12]))}" in line, line
    assert doctor_lines(audit_stderr) == expected
    build = run_chunkc("build", spec)
    assert doctor_lines(build.stderr) == expected, build.stderr
    assert "the dataset doctor took" in build.stderr


def test_plan_audit_and_build_judge_the_same_episodes(tmp_path):
    """Episodes the timing audit excludes (holes of more than `max_dropped` frames) are never
    read by the build, so `plan` and `audit` must not judge them either: the same lines, the same
    counts, counted in episodes of the episodes judged (issue 37: plan said clipped 34 of 50
    where build said 28 of 43)."""
    out = tmp_path / "d"
    run_chunkc("synth", out, "--format", "lerobot", "--episodes", 80, "--steps", 150,
               "--action-dim", 6, "--state-dim", 6, "--fps", 10, "--seed", 0,
               "--faults", "jump,scale:10,drop:0.3", "--fault-fraction", 0.1)
    spec = out / "spec.toml"
    run_chunkc("audit", spec)
    audit = json.loads((out / "out" / "audit" / "audit.json").read_text())
    timing_excluded = [e["id"] for e in audit["episodes"]
                       if e["verdict"] == "exclude" and not e.get("findings")]
    assert len(timing_excluded) >= 5, timing_excluded
    judged = len(audit["episodes"]) - len(timing_excluded)
    lines = doctor_lines("\n".join(audit["warnings"]))
    assert lines and all(f" of {judged} episodes" in l for l in lines), lines
    # The excluded episodes carry no doctor flag: they were not judged.
    assert not any(f["flag"] for e in audit["episodes"] if e["id"] in timing_excluded
                   for f in e.get("findings", []))
    plan = run_chunkc("plan", spec)
    assert doctor_lines(plan.stdout + plan.stderr) == lines
    build = run_chunkc("build", spec)
    assert doctor_lines(build.stderr) == lines
    meta = json.loads((out / "out" / "act" / "meta.json").read_text())
    reasons = {e["id"]: e["reason"] for e in meta["excluded"]}
    assert sorted(reasons) == sorted(timing_excluded)
    # An exclusion's reason is the audit's: no doctor finding reads as its cause.
    assert all(r.startswith("audit: ") and "jump: " not in r and "units: " not in r
               for r in reasons.values()), reasons


def test_the_doctor_does_not_change_the_outputs(tmp_path):
    spec = synth(tmp_path, "s")
    out = spec.parent / "out" / "act"
    run_chunkc("build", spec)
    on = {k: (out / k).read_bytes() for k in hashes(out)}
    spec.write_text(spec.read_text() + "\n[audit.doctor]\nenabled = false\n")
    assert "the dataset doctor" not in run_chunkc("build", spec).stderr
    off = {k: (out / k).read_bytes() for k in hashes(out)}
    assert on.keys() == off.keys()
    # Only the spec's hash (in meta.json and the README) differs: the spec did; and the card's
    # audit section, which says whether the doctor ran and what it found.
    def unhashed(files):
        h = json.loads(files["meta.json"])["spec_hash"]
        out = {k: v.replace(h.encode(), b"H").replace(h[:16].encode(), b"H") for k, v in files.items()}
        card = out["README.md"].decode()
        out["README.md"] = (card[:card.index("## Audit")] + card[card.index("## Storage"):]).encode()
        return out
    assert sorted(k for k in on if on[k] != off[k]) == ["README.md", "meta.json"]
    assert unhashed(on) == unhashed(off)


def test_build_excludes_and_errors_as_the_audit_does(tmp_path):
    spec = synth(tmp_path, "s", faults="scale:100")
    text = spec.read_text()
    spec.write_text(text + '\n[audit.doctor]\nunits = "exclude"\n')
    run_chunkc("audit", spec)
    audit = json.loads((spec.parent / "out" / "audit" / "audit.json").read_text())
    units = sorted(e["id"] for e in audit["episodes"] if "units" in e["flags"])
    truth = scaled(spec)
    assert units == truth and len(units) == 8
    run_chunkc("build", spec)
    meta = json.loads((spec.parent / "out" / "act" / "meta.json").read_text())
    assert sorted(e["id"] for e in meta["excluded"]) == units
    # The reason names what excluded the episode, not its other (warn-only) findings.
    assert all(e["reason"].startswith("dataset doctor: units: ") for e in meta["excluded"])
    others = {"jump", "frozen", "clipped", "duplicate", "misaligned", "mixed_convention", "short"}
    assert not any(f"{o}: " in e["reason"] for e in meta["excluded"] for o in others)
    assert sorted(set(range(80)) - set(meta["episodes"])) == units
    # An `= "error"` finding fails the build, naming the check and the episode; nothing is
    # written (a fresh output directory stays without the profile).
    spec.write_text(text.replace('dir = "out"', 'dir = "err"') + '\n[audit.doctor]\nunits = "error"\n')
    proc = run_chunkc("build", spec, check=False)
    assert proc.returncode != 0
    assert "units" in proc.stderr and f"episode {units[0]}" in proc.stderr, proc.stderr
    assert not (spec.parent / "err" / "act").exists()


def test_non_finite_and_doctor_exclusions_together(tmp_path):
    """A NaN stops the first pass before the doctor judges; the second pass (without the NaN
    episode) judges, its exclusions make a third: the output leaves both out."""
    spec = synth(tmp_path, "s", faults="scale:100")
    root = zarr.open(str(spec.parent / "replay.zarr"), mode="r+")
    ends = np.asarray(root["meta/episode_ends"][:])
    units = scaled(spec)
    nan_episode = next(e for e in range(80) if e not in units)
    start = 0 if nan_episode == 0 else int(ends[nan_episode - 1])
    action = root["data/action"]
    row = action[start + 5]
    row[1] = np.nan
    action[start + 5] = row
    spec.write_text(spec.read_text() + '\n[audit]\nnon_finite = "exclude_episode"\n'
                    '[audit.doctor]\nunits = "exclude"\n')
    run_chunkc("build", spec)
    meta = json.loads((spec.parent / "out" / "act" / "meta.json").read_text())
    assert sorted(e["id"] for e in meta["excluded"]) == sorted(units + [nan_episode])
    assert sorted(set(range(80)) - set(meta["episodes"])) == sorted(units + [nan_episode])


def mixture_of(tmp: Path, extra: str = "") -> Path:
    """Two synthetic sources with planted faults as one training mixture (`a`: the faults above,
    `b`: units scaled by 100), each 80 episodes at 10 Hz."""
    a, b = synth(tmp, "a"), synth(tmp, "b", faults="scale:100,jump")
    sources = []
    for name, spec in (("a", a), ("b", b)):
        path = next(p for p in spec.parent.iterdir() if p.suffix == ".zarr")
        sources.append(f'[sources.{name}]\nformat = "diffusion_policy_zarr"\npath = "{path}"\nfps = 10\n'
                       f'[sources.{name}.channels]\naction = "action"\n"observation.state" = "state"\n')
    spec = tmp / "mixture.toml"
    spec.write_text("version = 1\n" + "".join(sources) + '[output]\ndir = "mix"\n'
                    '[profiles.act]\npreset = "act"\nfps = 10\nchunk = 8\n' + extra)
    return spec


def test_a_mixtures_build_judges_each_source_as_its_audit_does(tmp_path):
    """The doctor of each source of a mixture rides on the build's read; its findings are the
    ones `chunkc audit` finds reading that source in a pass of its own, and its exclusions act
    the same, in mixture ids."""
    spec = mixture_of(tmp_path)
    run_chunkc("audit", spec)
    expected, flagged = [], {}
    for name in ("a", "b"):
        audit = json.loads((tmp_path / "mix" / "audit" / name / "audit.json").read_text())
        expected += [f"sources.{name}: {l}" for l in doctor_lines("\n".join(audit["warnings"]))]
        flagged[name] = audit["doctor"]["flagged"]
    assert flagged["a"] and "units" in flagged["b"], flagged
    build = run_chunkc("build", spec)
    got = sorted(l.strip().removeprefix("warning: ") for l in build.stderr.splitlines()
                 if ": dataset doctor: `" in l)
    assert got == sorted(expected), build.stderr
    assert "the dataset doctor took" in build.stderr
    # Exclusions: `b`'s scaled episodes leave the mixture, by their mixture ids.
    spec.write_text(spec.read_text().replace('dir = "mix"', 'dir = "excl"') + '\n[audit.doctor]\nunits = "exclude"\n')
    run_chunkc("audit", spec)
    audit = json.loads((tmp_path / "excl" / "audit" / "b" / "audit.json").read_text())
    units = sorted(e["id"] for e in audit["episodes"] if "units" in e["flags"])
    assert len(units) == 8
    run_chunkc("build", spec)
    meta = json.loads((tmp_path / "excl" / "act" / "meta.json").read_text())
    offset = meta["sources"]["b"]["id_offset"]
    excluded = sorted(e["id"] for e in meta["excluded"])
    assert [i - offset for i in excluded if i >= offset] == units, meta["excluded"]
    assert all(e["reason"].startswith("dataset doctor: units: ") for e in meta["excluded"])
