"""How the HDF5 layouts store image frames (`image_compression`), and ALOHA frames read from every
source storage (one frame per chunk or several, uncompressed, which chunkc reads without HDF5; or
compressed, which goes through HDF5): every frame compared with the source as h5py reads it, and
the stored filters as h5py reports them."""

import h5py
import numpy as np
import pytest

import fixtures
from conftest import run_chunkc

H, W = 24, 32
LENGTHS = (9, 14, 11)
CAMS = fixtures.ALOHA_CAMS

PROFILES = """
[profiles.default]
preset = "act"
chunk = 4

[profiles.none]
preset = "act"
chunk = 4
image_compression = "none"

[profiles.gzip]
preset = "act"
chunk = 4
image_compression = "gzip"

[profiles.gzip6]
preset = "act"
chunk = 4
image_compression = "gzip"
image_compression_level = 6

[profiles.materialized]
preset = "act"
chunk = 4
layout = "materialized"

[profiles.virtual]
preset = "act"
chunk = 4
layout = "virtual"
image_compression = "gzip"
"""

# profile -> (h5py's `compression`, `compression_opts`)
EXPECTED = {
    "default": (None, None),
    "none": (None, None),
    "gzip": ("gzip", 1),
    "gzip6": ("gzip", 6),
    "materialized": (None, None),
    "virtual": ("gzip", 1),
}


def write_source(directory, storage):
    """ALOHA episodes whose frames are stored as `storage` says; returns {id: {cam: frames}}."""
    directory.mkdir(parents=True)
    rng = np.random.default_rng(3)
    written = {}
    for e, n in enumerate(LENGTHS):
        ep = {}
        with h5py.File(directory / f"episode_{e}.hdf5", "w") as f:
            f.create_dataset("action", data=rng.normal(size=(n, 14)).astype(np.float32))
            f.create_dataset("observations/qpos", data=rng.normal(size=(n, 14)).astype(np.float32))
            for c, cam in enumerate(CAMS):
                frames = fixtures.frames(n, H, W, seed=e * 10 + c)
                options = {
                    "one_per_chunk": dict(chunks=(1, H, W, 3)),  # ALOHA's recorder
                    "four_per_chunk": dict(chunks=(4, H, W, 3)),  # a partial last chunk
                    "contiguous": dict(),
                    "gzip": dict(chunks=(1, H, W, 3), compression="gzip", compression_opts=4),
                }[storage]
                f.create_dataset(f"observations/images/{cam}", data=frames, **options)
                ep[cam] = frames
        written[e] = ep
    return written


def spec(tmp_path, source):
    channels = "\n".join(f'"observation.{cam}" = "observations/images/{cam}"' for cam in CAMS)
    text = (f'version = 1\n[source]\nformat = "aloha_hdf5"\npath = "{source}"\n'
            f'[source.channels]\naction = "action"\n"observation.qpos" = "observations/qpos"\n'
            f'{channels}\n[split]\nval_fraction = 0.0\n[output]\ndir = "out"\n{PROFILES}')
    path = tmp_path / "spec.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("storage", ["one_per_chunk", "four_per_chunk", "contiguous", "gzip"])
def test_frames_equal_the_source_in_every_image_compression(tmp_path, storage):
    src = tmp_path / "src"
    write_source(src, storage)
    run_chunkc("build", "-q", "-j", "2", spec(tmp_path, src))
    for profile, (compression, opts) in EXPECTED.items():
        with h5py.File(tmp_path / "out" / profile / "data.h5", "r") as f:
            ids = f["meta/episode_ids"][:]
            ends = f["meta/episode_ends"][:]
            starts = np.concatenate([[0], ends[:-1]])
            for cam in CAMS:
                ds = f[f"data/observation.{cam}"]
                assert ds.chunks == (1, H, W, 3), profile
                assert ds.compression == compression, profile
                assert ds.compression_opts == opts, profile
                stored = ds[:]
                for e, lo, hi in zip(ids, starts, ends):
                    with h5py.File(src / f"episode_{e}.hdf5", "r") as s:
                        want = s[f"observations/images/{cam}"][:]
                    np.testing.assert_array_equal(stored[lo:hi], want, err_msg=f"{profile} {cam} {e}")


def test_uncompressed_frames_are_byte_identical_with_any_thread_count(tmp_path):
    src = tmp_path / "src"
    write_source(src, "one_per_chunk")
    path = spec(tmp_path, src)
    data = {}
    for threads in ("1", "2"):
        (tmp_path / "chunkc.lock").unlink(missing_ok=True)
        assert "built" in run_chunkc("build", "-q", "-j", threads, path).stderr
        data[threads] = {p: (tmp_path / "out" / p / "data.h5").read_bytes() for p in EXPECTED}
    assert data["1"] == data["2"]


@pytest.mark.parametrize("line, message", [
    ('image_compression = "zstd"', "unknown value `zstd` for `profiles.bad.image_compression`"),
    ('image_compression = "gzip"\nimage_compression_level = 10',
     "`image_compression_level` 10 is out of range for gzip (0..=9)"),
    ("image_compression_level = 2", "takes no `image_compression_level`"),
    ('format = "zarr"\nimage_compression = "gzip"', "`image_compression` needs `format = \"hdf5\"`"),
])
def test_bad_image_compression_is_a_spec_error(tmp_path, line, message):
    src = tmp_path / "src"
    write_source(src, "one_per_chunk")
    path = spec(tmp_path, src)
    path.write_text(path.read_text() + f'\n[profiles.bad]\npreset = "act"\nchunk = 4\n{line}\n')
    proc = run_chunkc("build", "-q", path, check=False)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr
    assert "spec.toml:" in proc.stderr  # located in the file
    assert not (tmp_path / "out").exists()  # no partial output
