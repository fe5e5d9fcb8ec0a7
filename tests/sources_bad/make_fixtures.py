"""Regenerate the broken sources next to this file (run from the repository root):
- corrupt.hdf5: the first 3000 bytes of tests/data/robosuite_panda_lift.hdf5 (a truncated file).
- num_samples_mismatch.hdf5: a robomimic file whose data/demo_1 says num_samples = 8 while its
  arrays have 7 steps.
"""
from pathlib import Path

import h5py
import numpy as np

HERE = Path(__file__).resolve().parent
(HERE / "corrupt.hdf5").write_bytes((HERE.parent / "data/robosuite_panda_lift.hdf5").read_bytes()[:3000])
with h5py.File(HERE / "num_samples_mismatch.hdf5", "w") as f:
    for i, n in enumerate([6, 7, 8]):
        g = f.create_group(f"data/demo_{i}")
        g.attrs["num_samples"] = n + (i == 1)
        g.create_dataset("actions", data=np.zeros((n, 7)))
        g.create_dataset("obs/eef_pos", data=np.zeros((n, 3)))
