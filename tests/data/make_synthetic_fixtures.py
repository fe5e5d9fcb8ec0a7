"""Regenerate the synthetic source fixtures the example specs read (no public ALOHA or LeRobot
v3.0 recording is small enough to vendor):

- aloha_sim_jpeg/: 3 ALOHA episodes (30, 45, 38 steps), cameras `top` and `left_wrist` stored
  JPEG-compressed (T, max_len) as act-plus-plus writes them, 48x64 frames.
- lerobot_v3_synthetic/: a LeRobot v3.0 dataset with 4 episodes in 2 data files.

Usage: python tests/data/make_synthetic_fixtures.py   (from the repository root)
Written with tests/python/fixtures.py, the same writers the Python tests use.
"""
import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "python"))

import fixtures  # noqa: E402

for name in ("aloha_sim_jpeg", "lerobot_v3_synthetic"):
    shutil.rmtree(HERE / name, ignore_errors=True)
fixtures.write_aloha(HERE / "aloha_sim_jpeg", compressed=True)
fixtures.write_lerobot_v3(HERE / "lerobot_v3_synthetic")
