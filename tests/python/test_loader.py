"""The generated loader: numpy-only use, and a torch DataLoader with worker processes."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import import_loader, loader_module, model_tier, run_chunkc, write_spec

PROFILES = """
[profiles.dp]
preset = "diffusion_policy"

[profiles.act]
preset = "act"
fps = 10
chunk = 20
padding = "zero"
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("loader")
    run_chunkc("build", "-q", write_spec(d, PROFILES))
    return d / "out"


def test_loader_works_without_torch(built):
    # Block torch before the loader imports it: the numpy-only path must still give samples.
    code = (
        "import sys; sys.modules['torch'] = None\n"
        f"sys.path.insert(0, {str(built / 'dp')!r})\n"
        "import loader, numpy as np\n"
        "ds = loader.ChunkedDataset(split='val')\n"
        "assert loader._DatasetBase is object\n"
        "s = ds[len(ds) - 1]\n"
        "assert s['action'].shape == (16, 2) and s['action_is_pad'].dtype == np.bool_\n"
        "assert s['observation.image'].shape == (2, 96, 96, 3) and s['observation.image'].dtype == np.uint8\n"
        "assert s['action_is_pad'][-1]\n"
        "b = ds.__getitems__([len(ds) - 1, 0])\n"
        "assert all(np.array_equal(b[0][k], s[k]) for k in s)\n"
        "print(len(ds))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout) > 0


@pytest.mark.parametrize("profile", ["dp", "act"])
def test_torch_dataloader_full_epoch_with_workers(built, profile):
    torch = model_tier("torch")
    loader = import_loader(built / profile)
    ds = loader.ChunkedDataset(str(built / profile), "train")
    assert isinstance(ds, torch.utils.data.Dataset)
    dl = loader.make_dataloader(str(built / profile), "train", batch_size=128, shuffle=False, num_workers=2)
    assert dl.prefetch_factor == 2
    seen = 0
    frames = []
    for batch in dl:
        k = ds.chunk_size
        assert batch["action"].dtype == torch.float32 and batch["action"].shape[1:] == (k, 2)
        assert batch["action_is_pad"].dtype == torch.bool
        assert batch["observation.image"].dtype == torch.uint8
        seen += batch["action"].shape[0]
        frames.append(batch["frame_index"].numpy())
    assert seen == len(ds)
    # The workers saw every sample once, in order (no shuffle).
    want = np.array([ds.index[i][1] for i in range(len(ds))])
    np.testing.assert_array_equal(np.concatenate(frames), want)


def test_in_memory_and_float_images_match_lazy_reads(built):
    loader = import_loader(built / "dp")
    lazy = loader.ChunkedDataset(str(built / "dp"), "val")
    memory = loader.ChunkedDataset(str(built / "dp"), "val", in_memory=True, image_dtype="float32")
    assert len(lazy) == len(memory)
    for i in range(0, len(lazy), 7):
        a, b = lazy[i], memory[i]
        np.testing.assert_array_equal(a["action"], b["action"])
        np.testing.assert_array_equal(a["observation.state"], b["observation.state"])
        assert b["observation.image"].dtype == np.float32
        np.testing.assert_allclose(b["observation.image"], a["observation.image"] / 255.0, rtol=1e-7)


FORMATS = """
[profiles.dp_hdf5]
preset = "diffusion_policy"
[profiles.act_hdf5]
preset = "act"
fps = 10
chunk = 20
[profiles.dp_zarr]
extends = "dp_hdf5"
format = "zarr"
[profiles.act_zarr]
extends = "act_hdf5"
format = "zarr"
[profiles.dp_parquet]
extends = "dp_hdf5"
format = "parquet"
[profiles.act_parquet]
extends = "act_hdf5"
format = "parquet"
"""


@pytest.fixture(scope="module")
def every_format(tmp_path_factory):
    d = tmp_path_factory.mktemp("formats")
    run_chunkc("build", "-q", write_spec(d, FORMATS))
    return d / "out"


@pytest.mark.parametrize("arch", ["dp", "act"])
@pytest.mark.parametrize("fmt", ["zarr", "parquet"])
def test_full_epoch_with_two_workers_in_every_format(every_format, arch, fmt):
    """A DataLoader with 2 workers iterates a whole epoch of each format, and its batches equal the
    HDF5 layout's batch for batch."""
    torch = model_tier("torch")
    root, reference = every_format / f"{arch}_{fmt}", every_format / f"{arch}_hdf5"
    loader = import_loader(root)
    assert loader.ChunkedDataset(str(root)).meta["data_format"] == fmt
    dl = loader.make_dataloader(str(root), "train", batch_size=256, num_workers=2, shuffle=False)
    ref = loader_module(reference).make_dataloader(str(reference), "train", batch_size=256, num_workers=2,
                                                   shuffle=False)
    seen = 0
    for batch, want in zip(dl, ref):
        assert set(batch) == set(want)
        for key in batch:
            torch.testing.assert_close(batch[key], want[key], rtol=0, atol=0)
        seen += len(batch["action"])
    assert seen == len(dl.dataset) == len(ref.dataset)


@pytest.mark.parametrize("other, patch, part", [
    ("dp_zarr", None, "hdf5"),
    ("dp_hdf5", {"transforms": [{"op": "delta", "channel": "action", "reference": "observation.state",
                                 "mask": [True, False]}]}, "transforms"),
    ("dp_hdf5", {"sources": {}}, "mixture"),
    ("dp_hdf5", {"sampling": {"mode": "hierarchy"}}, "hierarchy"),
])
def test_a_loader_refuses_a_meta_json_that_needs_a_part_it_lacks(every_format, tmp_path, other, patch, part):
    """Each profile's loader.py holds the parts its profile reads: copied beside a meta.json that
    needs another part (another format, transforms, a mixture, hierarchical samples), it refuses
    it, naming the part, rather than reading it wrong."""
    root = shutil.copytree(every_format / "dp_hdf5", tmp_path / f"needs_{part}")
    shutil.copy(every_format / other / "loader.py", root / "loader.py")
    if patch:
        meta = json.loads((root / "meta.json").read_text())
        meta.update(patch)
        (root / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=f"needs the {part} part"):
        loader_module(root).ChunkedDataset(str(root))
