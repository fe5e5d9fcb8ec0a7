"""Regenerate tests/data/pusht_subset.zarr from the full Push-T replay buffer.

Usage: python tests/data/make_pusht_subset.py PATH/TO/pusht_cchi_v7_replay.zarr

Keeps the first N_EPISODES episodes with the source's own chunking and Blosc settings, so the
subset exercises the same decoding path as the full dataset.
"""
import os
import sys

import numpy as np
import zarr

N_EPISODES = int(os.environ.get("N_EPISODES", "20"))


def main(src_path: str, dst_path: str = "tests/data/pusht_subset.zarr") -> None:
    src = zarr.open(src_path, mode="r")
    ends = src["meta/episode_ends"][:N_EPISODES]
    n = int(ends[-1])
    dst = zarr.open_group(dst_path, mode="w")
    meta = dst.create_group("meta")
    meta.array("episode_ends", ends.astype(np.int64), chunks=src["meta/episode_ends"].chunks,
               compressor=src["meta/episode_ends"].compressor)
    data = dst.create_group("data")
    for key, arr in src["data"].items():
        data.array(key, arr[:n], chunks=arr.chunks, compressor=arr.compressor, dtype=arr.dtype)
    print(f"wrote {N_EPISODES} episodes, {n} steps to {dst_path}")


if __name__ == "__main__":
    main(*sys.argv[1:])
