"""The README's claims, checked: its spec block is specs/pusht.toml, its quick start runs, its
Python snippet runs on a build of that spec and returns what its comments say, the files and
commands it lists exist, and its format table is the schema's."""

import json
import re
import shutil
import subprocess
import sys
import tomllib

import pytest

from conftest import REPO, run_chunkc

README = (REPO / "README.md").read_text()


def blocks(lang):
    return re.findall(rf"^```{lang}\n(.*?)^```", README, flags=re.S | re.M)


def test_spec_block_is_the_shipped_spec():
    (spec,) = blocks("toml")
    assert "specs/pusht.toml" in README
    assert tomllib.loads(spec) == tomllib.loads((REPO / "specs" / "pusht.toml").read_text())


@pytest.fixture(scope="module")
def pusht(tmp_path_factory):
    """specs/pusht.toml built in a scratch copy of the layout it expects (specs/, tests/data)."""
    root = tmp_path_factory.mktemp("readme")
    (root / "specs").mkdir()
    (root / "tests").mkdir()
    (root / "tests" / "data").symlink_to(REPO / "tests" / "data")
    shutil.copy(REPO / "specs" / "pusht.toml", root / "specs" / "pusht.toml")
    run_chunkc("build", "-q", root / "specs" / "pusht.toml")
    return root


def test_python_snippet_runs_and_its_comments_hold(pusht):
    (snippet,) = blocks("python")
    # The shapes the comments promise, read from the comments themselves.
    claims = {k: tuple(int(d) for d in v.split(",") if d.strip())
              for k, v in re.findall(r'"([\w.]+)" \(([\d, ]+)\)', snippet)}
    assert {"action", "action_is_pad", "observation.state", "observation.image"} <= claims.keys()
    check = snippet + "\n" + "\n".join([
        "import json",
        "print(json.dumps({k: list(getattr(v, 'shape', ())) for k, v in s.items()}))",
        "assert raw.shape == s['action'].shape and raw.dtype.kind == 'f'",
        "assert s['observation.image'].dtype.name == 'uint8'",
        "assert s['action'].dtype.name == 'float32'",
    ])
    proc = subprocess.run([sys.executable, "-c", check], cwd=pusht, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    shapes = json.loads(proc.stdout.strip().splitlines()[-1])
    for key, shape in claims.items():
        assert tuple(shapes[key]) == shape, key
    for key in ("observation.state_is_pad", "observation.image_is_pad", "episode_index", "frame_index"):
        assert key in shapes


def test_listed_files_and_meta_keys_exist(pusht):
    table = README.split("## What a build writes")[1].split("```python")[0]
    profile = pusht / "out" / "pusht" / "dp"
    for name in re.findall(r"^\| `([\w.]+)`", table, flags=re.M):
        assert (profile / name).exists(), name
    for name in ("README.md", "validate.py", "smoke_train.py", "dp_normalizer.json", "dp_normalizer.py"):
        assert (profile / name).exists(), name
    assert (pusht / "out" / "pusht" / "act" / "dataset_stats.pkl").exists()
    meta = json.loads((profile / "meta.json").read_text())
    row = next(line for line in table.splitlines() if line.startswith("| `meta.json`"))
    for key in re.findall(r"`(\w+)`", row.split("|")[2]):
        if key not in ("mode", "center", "scale", "clip"):
            assert key in meta or key in meta["sampling"] or key in meta["normalization"]["action"], key
    assert (pusht / "specs" / "chunkc.lock").exists()


def test_command_table_matches_the_cli():
    table = README.split("## Command line")[1].split("## Documentation")[0]
    rows = re.findall(r"^\| `chunkc (\w+)([^`]*)`", table, flags=re.M)
    assert {cmd for cmd, _ in rows} >= {"check", "audit", "plan", "build", "analyze", "schema"}
    for cmd, args in rows:
        helptext = run_chunkc(cmd, "--help").stdout
        for flag in re.findall(r"(--[\w-]+|-\w)\b", args):
            assert flag in helptext, (cmd, flag)
    for flag in ("--threads", "-j"):
        assert flag in run_chunkc("--help").stdout


def test_format_table_is_the_schema():
    schema = json.loads(run_chunkc("schema").stdout)
    defs = schema.get("$defs", schema.get("definitions"))
    formats = {v["const"] for v in defs["OutputFormat"]["oneOf"]}
    table = README.split("A\nprofile's `format` is one of:")[1].split("\n\n")[1]
    listed = re.findall(r"^\| `(\w+)`", table, flags=re.M)[1:]  # after the header
    assert set(listed) == formats
    sources = {v["const"] for v in defs["SourceFormat"]["oneOf"]}
    for name in sources:
        assert f"`{name}`" in README, name
    assert "rejected with a clear error until" not in README


def test_quick_start_installs_the_wheel_first():
    """The quick start begins with the wheel, then runs the installed `chunkc` (no target/ path)."""
    first = README.split("## Quick start")[1].split("Working on chunkc itself")[0]
    install, use = [b for b in blocks("sh") if b in first][:2]
    assert install.splitlines()[0].startswith("pip install dist/chunkc-*.whl")
    assert 'pip install "chunkc[loader]"' in install
    assert all(line.startswith("chunkc ") for line in use.splitlines() if line.strip())
    assert "target/release" not in first.split("Working on")[0]


def test_quick_start_runs():
    (quick,) = [b for b in blocks("sh") if "scripts/demo.sh" in b]
    commands = [line.split("#")[0].split() for line in quick.splitlines() if line.strip()]
    scripts = {c[0] for c in commands}
    assert scripts == {"scripts/demo.sh", "scripts/test.sh", "scripts/fuzz.sh", "scripts/wheel.sh"}
    # scripts/test.sh is the suite this test runs in (CI calls it through .ci/run); fuzz.sh runs
    # the fuzzers for minutes and is run by test.sh itself when cargo-fuzz is there; wheel.sh is
    # run by test.sh too, and its wheel tested by test_wheel.py. All are checked to be what the
    # README says; demo.sh is run.
    assert "scripts/test.sh" in (REPO / ".ci" / "run").read_text()
    assert "scripts/wheel.sh" in (REPO / "scripts" / "test.sh").read_text()
    for script in scripts:
        assert subprocess.run(["bash", "-n", str(REPO / script)]).returncode == 0
    proc = subprocess.run([str(REPO / "scripts" / "demo.sh")], cwd="/", capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert "demo: done" in proc.stdout
    assert "action (16, 2)" in proc.stdout
