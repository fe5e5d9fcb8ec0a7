"""RLDS / Open X-Embodiment sources (`format = "rlds"`), checked against an independent reader:
the `tfrecord` package for the framing, `protobuf` (tfrecord's `example_pb2`) for the
`tf.train.Example`s, and libjpeg-turbo called here through its libjpeg API (ctypes) with the
settings of TensorFlow's `decode_jpeg` (fast integer IDCT, fancy upsampling), the decode TFDS
applies. The Bridge fixture (tests/data/rlds-bridge, MIT) is real Octo debug data."""

import ctypes
import glob
import json
import os
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest
import PIL
from tfrecord import example_pb2
from tfrecord.reader import tfrecord_iterator
from tfrecord.writer import TFRecordWriter

import reference
from conftest import REPO, bits, load_dataset as load, run_chunkc

BRIDGE = REPO / "tests" / "data" / "rlds-bridge" / "bridge_dataset"
VERSION = BRIDGE / "1.0.0"
CAMERAS = [f"image_{i}" for i in range(4)]


# --- JPEG as TensorFlow decodes it -------------------------------------------------------------

JDCT_ISLOW, JDCT_IFAST, JCS_RGB = 0, 1, 2
STRUCT_SIZE, ERR_SIZE = 632, 168  # sizeof(jpeg_decompress_struct), sizeof(jpeg_error_mgr): 6.2 ABI, LP64


class _Fields(ctypes.Structure):
    # The leading fields of `struct jpeg_decompress_struct` (jpeglib.h), up to output_scanline.
    _fields_ = [
        ("err", ctypes.c_void_p), ("mem", ctypes.c_void_p), ("progress", ctypes.c_void_p),
        ("client_data", ctypes.c_void_p), ("is_decompressor", ctypes.c_int), ("global_state", ctypes.c_int),
        ("src", ctypes.c_void_p), ("image_width", ctypes.c_uint), ("image_height", ctypes.c_uint),
        ("num_components", ctypes.c_int), ("jpeg_color_space", ctypes.c_int), ("out_color_space", ctypes.c_int),
        ("scale_num", ctypes.c_uint), ("scale_denom", ctypes.c_uint), ("output_gamma", ctypes.c_double),
        ("buffered_image", ctypes.c_int), ("raw_data_out", ctypes.c_int), ("dct_method", ctypes.c_int),
        ("do_fancy_upsampling", ctypes.c_int), ("do_block_smoothing", ctypes.c_int),
        ("quantize_colors", ctypes.c_int), ("dither_mode", ctypes.c_int), ("two_pass_quantize", ctypes.c_int),
        ("desired_number_of_colors", ctypes.c_int), ("enable_1pass_quant", ctypes.c_int),
        ("enable_external_quant", ctypes.c_int), ("enable_2pass_quant", ctypes.c_int),
        ("output_width", ctypes.c_uint), ("output_height", ctypes.c_uint),
        ("out_color_components", ctypes.c_int), ("output_components", ctypes.c_int),
        ("rec_outbuf_height", ctypes.c_int), ("actual_number_of_colors", ctypes.c_int),
        ("colormap", ctypes.c_void_p), ("output_scanline", ctypes.c_uint),
    ]


class _Decompress(ctypes.Structure):
    _fields_ = [("f", _Fields), ("_rest", ctypes.c_char * (STRUCT_SIZE - ctypes.sizeof(_Fields)))]


def _libjpeg():
    """Pillow's bundled libjpeg-turbo (SIMD build, as TensorFlow's), else the system's."""
    here = Path(PIL.__file__).parent.parent / "pillow.libs"
    for path in sorted(glob.glob(str(here / "libjpeg*.so*"))) + ["libjpeg.so.62"]:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        lib.jpeg_std_error.restype = ctypes.c_void_p
        lib.jpeg_std_error.argtypes = [ctypes.c_void_p]
        lib.jpeg_CreateDecompress.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]
        lib.jpeg_mem_src.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_ulong]
        lib.jpeg_read_header.argtypes = [ctypes.c_void_p, ctypes.c_int]
        for name in ("jpeg_start_decompress", "jpeg_finish_decompress", "jpeg_destroy_decompress"):
            getattr(lib, name).argtypes = [ctypes.c_void_p]
        lib.jpeg_read_scanlines.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint]
        lib.jpeg_read_scanlines.restype = ctypes.c_uint
        return lib
    pytest.skip("no libjpeg 6.2 ABI library to decode JPEG with TensorFlow's settings")


_LIB = None


def decode_tf(data: bytes, dct_method=JDCT_IFAST) -> np.ndarray:
    """(H, W, 3) uint8, as `tf.io.decode_jpeg(data, channels=3)` gives it."""
    global _LIB
    _LIB = _LIB or _libjpeg()
    assert _Fields.dct_method.offset == 96 and _Fields.output_scanline.offset == 168  # x86-64 ABI
    cinfo = _Decompress()
    err = ctypes.create_string_buffer(ERR_SIZE)
    cinfo.f.err = _LIB.jpeg_std_error(err)
    _LIB.jpeg_CreateDecompress(ctypes.byref(cinfo), 62, STRUCT_SIZE)
    try:
        buf = ctypes.create_string_buffer(data, len(data))
        _LIB.jpeg_mem_src(ctypes.byref(cinfo), buf, len(data))
        _LIB.jpeg_read_header(ctypes.byref(cinfo), 1)
        cinfo.f.out_color_space = JCS_RGB
        cinfo.f.dct_method = dct_method
        cinfo.f.do_fancy_upsampling = 1
        _LIB.jpeg_start_decompress(ctypes.byref(cinfo))
        h, w, c = cinfo.f.output_height, cinfo.f.output_width, cinfo.f.output_components
        out = np.zeros((h, w, c), dtype=np.uint8)
        row = (ctypes.c_void_p * 1)()
        while cinfo.f.output_scanline < h:
            row[0] = out[cinfo.f.output_scanline].ctypes.data
            _LIB.jpeg_read_scanlines(ctypes.byref(cinfo), row, 1)
        _LIB.jpeg_finish_decompress(ctypes.byref(cinfo))
        return out
    finally:
        _LIB.jpeg_destroy_decompress(ctypes.byref(cinfo))


# --- the independent reader --------------------------------------------------------------------

def step_shapes(version: Path):
    """Per-step features of features.json: {flattened key: (kind, shape)}."""
    out = {}

    def walk(node, path, steps):
        cls = node["pythonClassName"].rsplit(".", 1)[-1]
        if cls == "FeaturesDict":
            for k, v in node["featuresDict"]["features"].items():
                walk(v, path + [k], steps)
        elif cls == "Dataset":
            walk(node["sequence"]["feature"], path, True)
        elif steps and cls in ("Tensor", "Scalar"):
            out["/".join(path)] = ("tensor", tuple(int(d) for d in node["tensor"]["shape"].get("dimensions", [])))
        elif steps and cls == "Image":
            out["/".join(path)] = ("image", tuple(int(d) for d in node["image"]["shape"]["dimensions"]))

    walk(json.loads((version / "features.json").read_text()), [], False)
    return out


def read_split(version: Path, split: str, keys):
    """Each episode of a TFDS split, in shard and record order: {key: (T, ...) array, "task": str}."""
    info = json.loads((version / "dataset_info.json").read_text())
    shapes = step_shapes(version)
    (entry,) = [s for s in info["splits"] if s["name"] == split]
    n = len(entry["shardLengths"])
    episodes = []
    for x in range(n):
        path = version / f"{info['name']}-{split}.tfrecord-{x:05d}-of-{n:05d}"
        for record in tfrecord_iterator(str(path)):
            ex = example_pb2.Example()
            ex.ParseFromString(record)
            f = ex.features.feature
            ep = {}
            for key in keys:
                kind, shape = shapes[key]
                if kind == "image":
                    ep[key] = np.stack([decode_tf(b) for b in f[key].bytes_list.value])
                else:
                    lst = f[key].float_list.value if f[key].HasField("float_list") else f[key].int64_list.value
                    ep[key] = np.asarray(lst, dtype=np.float32).reshape((-1,) + (shape or (1,)))
            instr = f["steps/language_instruction"].bytes_list.value if "steps/language_instruction" in f else []
            ep["task"] = instr[0].decode() if instr else None
            episodes.append(ep)
    return episodes


def rlds_spec(directory: Path, source: Path, channels: dict, profiles: str, fps=5, split='from = "source"',
              extra_source=""):
    def value(v):
        if isinstance(v, list):
            return "{ concat = [" + ", ".join(f'"{k}"' for k in v) + "] }"
        return f'"{v}"'

    lines = ["version = 1", "[source]", 'format = "rlds"', f'path = "{source}"']
    if fps is not None:
        lines.append(f"fps = {fps}")
    lines += [extra_source, "[source.channels]", *[f'"{k}" = {value(v)}' for k, v in channels.items()],
              "[split]", split, "[output]", 'dir = "out"', profiles]
    spec = directory / "spec.toml"
    spec.write_text("\n".join(lines) + "\n")
    return spec


BRIDGE_CHANNELS = {
    "action": "steps/action",
    "observation.state": "steps/observation/state",
    "observation.reward": "steps/reward",
    "observation.discount": "steps/discount",
    "observation.is_first": "steps/is_first",
    **{f"observation.images.{c}": f"steps/observation/{c}" for c in CAMERAS},
}
LOWDIM = [k for k in BRIDGE_CHANNELS if "images" not in k]


@pytest.fixture(scope="module")
def oracle():
    keys = list(BRIDGE_CHANNELS.values())
    return {s: read_split(VERSION, s, keys) for s in ("train", "val")}


@pytest.fixture(scope="module")
def raw_build(tmp_path_factory):
    d = tmp_path_factory.mktemp("rlds_raw")
    norm = ", ".join(f'"{k}" = "none"' for k in BRIDGE_CHANNELS)
    spec = rlds_spec(d, BRIDGE, BRIDGE_CHANNELS,
                     f'[profiles.raw]\npreset = "act"\nfps = 5\nchunk = 4\nformat = "hdf5"\nnormalize = {{ {norm} }}\n')
    run_chunkc("build", "-q", spec)
    return d / "out" / "raw"


def test_every_step_of_both_splits_equals_the_independent_reader(raw_build, oracle):
    import h5py

    meta = json.loads((raw_build / "meta.json").read_text())
    n_train, n_val = len(oracle["train"]), len(oracle["val"])
    assert (n_train, n_val) == (25, 25)
    # TFDS's splits kept: train -> train, val -> val; ids in split, shard and record order.
    assert meta["split"] == {"train": list(range(n_train)), "val": list(range(n_train, n_train + n_val))}
    assert meta["source"]["format"] == "rlds"
    # Each episode's language instruction is its task.
    assert meta["tasks"] == {str(i): e["task"] for i, e in enumerate(oracle["train"] + oracle["val"])}
    episodes = oracle["train"] + oracle["val"]
    ends = np.asarray(meta["episode_ends"])
    assert list(np.diff(np.concatenate([[0], ends]))) == [len(e["steps/action"]) for e in episodes]
    with h5py.File(raw_build / "data.h5") as f:
        for name, key in BRIDGE_CHANNELS.items():
            got = f[f"data/{name}"][:]
            want = np.concatenate([e[key] for e in episodes])
            if "images" in name:
                assert got.dtype == np.uint8 and got.shape == want.shape
                assert np.array_equal(got, want), name  # bit for bit with TF's decode
            else:
                assert np.array_equal(bits(got.astype(np.float32)), bits(want.reshape(got.shape))), name


def test_the_audit_reports_the_step_markers(raw_build, oracle):
    """Bridge sets `is_first` only: the audit warns about `is_last`, and builds anyway."""
    spec = raw_build.parent.parent / "spec.toml"
    proc = run_chunkc("audit", spec)
    report = json.loads((raw_build.parent / "audit" / "audit.json").read_text())
    n = len(oracle["train"]) + len(oracle["val"])
    assert any("is_last" in w and f"{n} of {n} episodes" in w for w in report["warnings"]), report["warnings"]
    assert not any("is_first" in w for w in report["warnings"])
    assert "is_last" in proc.stdout + proc.stderr


def test_frames_are_not_the_accurate_dct_decode():
    """What the fast-IDCT requirement is about: the accurate IDCT (Pillow's default) gives
    other frames on Bridge, by up to 17 levels."""
    import io

    from PIL import Image

    ex = example_pb2.Example()
    ex.ParseFromString(next(iter(tfrecord_iterator(str(VERSION / "bridge_dataset-train.tfrecord-00000-of-00001")))))
    frame = ex.features.feature["steps/observation/image_0"].bytes_list.value[0]
    pil = np.asarray(Image.open(io.BytesIO(frame)).convert("RGB"))
    assert np.array_equal(decode_tf(frame, JDCT_ISLOW), pil)  # the ctypes decoder is sound
    differ = total = 0
    worst = 0
    for record in tfrecord_iterator(str(VERSION / "bridge_dataset-train.tfrecord-00000-of-00001")):
        ex = example_pb2.Example()
        ex.ParseFromString(record)
        for c in CAMERAS:
            for b in ex.features.feature[f"steps/observation/{c}"].bytes_list.value:
                a, s = decode_tf(b).astype(int), decode_tf(b, JDCT_ISLOW).astype(int)
                total += 1
                differ += int((a != s).any())
                worst = max(worst, int(np.abs(a - s).max()))
    assert total == 1000 and differ > 0 and worst > 1


PROFILES = {
    "act": 'preset = "act"\nfps = 5\nchunk = 4',
    "dp": 'preset = "diffusion_policy"\nfps = 5\nchunk = 8',
}


@pytest.fixture(scope="module")
def every_format(tmp_path_factory):
    d = tmp_path_factory.mktemp("rlds_formats")
    channels = {k: BRIDGE_CHANNELS[k] for k in ("action", "observation.state", "observation.images.image_0")}
    profiles = "\n".join(f'[profiles.{arch}_{fmt}]\n{keys}\nformat = "{fmt}"\n'
                         for arch, keys in PROFILES.items() for fmt in ("hdf5", "zarr", "parquet"))
    run_chunkc("build", "-q", rlds_spec(d, BRIDGE, channels, profiles))
    return d / "out"


@pytest.mark.parametrize("arch", PROFILES)
@pytest.mark.parametrize("fmt", ["hdf5", "zarr", "parquet"])
def test_loader_windows_equal_numpy_windows_over_the_reader(every_format, oracle, arch, fmt):
    root = every_format / f"{arch}_{fmt}"
    meta = json.loads((root / "meta.json").read_text())
    episodes = oracle["train"] + oracle["val"]
    K, n_obs, lead = meta["chunk_size"], meta["obs_history"], meta.get("action_lead", 0) or 0
    params = {name: (np.asarray(p["center"], dtype=np.float64).reshape(-1),
                     np.asarray(p["scale"], dtype=np.float64).reshape(-1), p["clip"])
              for name, p in meta["normalization"].items() if p.get("mode", "none") != "none" and "center" in p}
    for split in ("train", "val"):
        ds = load(root, split)
        ids = meta["split"][split]
        want_n = sum(len(reference.expected_starts(len(episodes[e]["steps/action"]), K, n_obs, meta["padding"],
                                                   meta["stride"], lead, meta.get("max_pad_after")))
                     for e in ids)
        assert len(ds) == want_n == meta["num_samples"][split]
        for i in range(len(ds)):
            s = ds[i]
            e, t = int(s["episode_index"]), int(s["frame_index"])
            assert e in ids
            ep = episodes[e]
            action, is_pad = reference.action_window(ep["steps/action"], t, K, meta["padding"], params["action"], lead)
            np.testing.assert_allclose(s["action"], action, rtol=1e-5, atol=1e-5)
            assert np.array_equal(s["action_is_pad"], is_pad)
            state = reference.obs_window(ep["steps/observation/state"], t, n_obs)
            np.testing.assert_allclose(s["observation.state"], reference.normalize(state, params["observation.state"]),
                                       rtol=1e-5, atol=1e-5)
            frames = reference.obs_window(ep["steps/observation/image_0"], t, n_obs)
            got = np.asarray(s["observation.images.image_0"])
            if got.dtype != np.uint8:  # float images in [0, 1] (the DP normalizer maps them on)
                got = np.rint(np.asarray(ds.denormalize("observation.images.image_0", got)) * (255 if got.max() <= 1.0 + 1e-6 else 1))
            assert np.array_equal(got.astype(np.uint8), frames), (split, i)


# --- an RT-1 style dataset written here with the tfrecord package -----------------------------

def tensor(shape, dtype="float32"):
    cls = "scalar.Scalar" if not shape else "tensor_feature.Tensor"
    return {"pythonClassName": f"tensorflow_datasets.core.features.{cls}",
            "tensor": {"shape": {"dimensions": [str(d) for d in shape]}, "dtype": dtype, "encoding": "none"}}


def fdict(features):
    return {"pythonClassName": "tensorflow_datasets.core.features.features_dict.FeaturesDict",
            "featuresDict": {"features": features}}


def write_rt1(root: Path, lengths=(7, 12, 5, 9), shards=2, seed=0):
    """A fractal-like RLDS set: nested action dict, a ragged feature, text, bools."""
    rng = np.random.default_rng(seed)
    version = root / "1.0.0"
    version.mkdir(parents=True)
    steps = fdict({
        "action": fdict({"world_vector": tensor([3]), "rotation_delta": tensor([3]),
                         "gripper_closedness_action": tensor([1]), "terminate_episode": tensor([3], "int32")}),
        "observation": fdict({"base_pose": tensor([2], "float64"), "points": tensor([-1, 2])}),
        "is_first": tensor([], "bool"), "is_last": tensor([], "bool"), "is_terminal": tensor([], "bool"),
        "reward": tensor([]),
        "language_instruction": {"pythonClassName": "tensorflow_datasets.core.features.text_feature.Text", "text": {}},
    })
    features = fdict({"steps": {"pythonClassName": "tensorflow_datasets.core.features.dataset_feature.Dataset",
                                "sequence": {"feature": steps, "length": "-1"}},
                      "episode_metadata": fdict({"file_path": {
                          "pythonClassName": "tensorflow_datasets.core.features.text_feature.Text", "text": {}}})})
    (version / "features.json").write_text(json.dumps(features))
    per_shard = [list(range(len(lengths)))[x::shards] for x in range(shards)]
    per_shard = [sorted(p) for p in per_shard]
    order = [e for p in per_shard for e in p]
    episodes = {}
    for x, eps in enumerate(per_shard):
        w = TFRecordWriter(str(version / f"fractal-train.tfrecord-{x:05d}-of-{shards:05d}"))
        for e in eps:
            T = lengths[e]
            ep = {"world_vector": rng.standard_normal((T, 3)).astype(np.float32),
                  "rotation_delta": rng.standard_normal((T, 3)).astype(np.float32),
                  "gripper": rng.uniform(-1, 1, (T, 1)).astype(np.float32),
                  "terminate": np.eye(3, dtype=np.int64)[np.minimum(np.arange(T), 2)],
                  "base_pose": rng.standard_normal((T, 2)).astype(np.float32),
                  "points": rng.standard_normal((T, 3, 2)).astype(np.float32),
                  "task": f"task {e % 2}"}
            episodes[e] = ep
            flag = lambda at: [int(s == at) for s in range(T)]  # noqa: E731
            w.write({
                "steps/action/world_vector": (ep["world_vector"].ravel().tolist(), "float"),
                "steps/action/rotation_delta": (ep["rotation_delta"].ravel().tolist(), "float"),
                "steps/action/gripper_closedness_action": (ep["gripper"].ravel().tolist(), "float"),
                "steps/action/terminate_episode": (ep["terminate"].ravel().tolist(), "int"),
                "steps/observation/base_pose": (ep["base_pose"].ravel().tolist(), "float"),
                "steps/observation/points/ragged_flat_values": (ep["points"].ravel().tolist(), "float"),
                "steps/observation/points/ragged_row_lengths_0": ([3] * T, "int"),
                "steps/is_first": (flag(0), "int"),
                "steps/is_last": (flag(T - 1 if e != 1 else -5), "int"),
                "steps/is_terminal": (flag(T - 1), "int"),
                "steps/reward": ([0.0] * T, "float"),
                "steps/language_instruction": ([ep["task"].encode()] * T, "byte"),
                "episode_metadata/file_path": ([f"/data/ep{e}".encode()], "byte"),
            })
        w.close()
    info = {"name": "fractal", "fileFormat": "tfrecord", "version": "1.0.0",
            "splits": [{"name": "train", "filepathTemplate": "{DATASET}-{SPLIT}.{FILEFORMAT}-{SHARD_X_OF_Y}",
                        "shardLengths": [str(len(p)) for p in per_shard]}]}
    (version / "dataset_info.json").write_text(json.dumps(info))
    return version, [episodes[e] for e in order]


RT1_CHANNELS = {
    "action": ["steps/action/world_vector", "steps/action/rotation_delta", "steps/action/gripper_closedness_action"],
    "observation.terminate": "steps/action/terminate_episode",
    "observation.base_pose": "steps/observation/base_pose",
    "observation.points": "steps/observation/points",
}


def test_nested_actions_concatenate_and_ragged_rows_flatten(tmp_path):
    import h5py

    version, episodes = write_rt1(tmp_path / "fractal")
    norm = ", ".join(f'"{k}" = "none"' for k in RT1_CHANNELS)
    spec = rlds_spec(tmp_path, version.parent, RT1_CHANNELS,
                     f'[profiles.raw]\npreset = "act"\nfps = 3\nchunk = 2\nformat = "hdf5"\nnormalize = {{ {norm} }}\n',
                     fps=3, split="val_fraction = 0.0\nseed = 0")
    proc = run_chunkc("build", "-q", spec)
    with h5py.File(tmp_path / "out" / "raw" / "data.h5") as f:
        want = np.concatenate([np.concatenate([e["world_vector"], e["rotation_delta"], e["gripper"]], axis=1)
                               for e in episodes])
        assert np.array_equal(f["data/action"][:], want)
        assert np.array_equal(f["data/observation.terminate"][:], np.concatenate([e["terminate"] for e in episodes]))
        # float64 is stored as float32 by TFDS: read as stored.
        assert np.array_equal(f["data/observation.base_pose"][:], np.concatenate([e["base_pose"] for e in episodes]))
        pts = f["data/observation.points"][:]
        assert np.array_equal(pts.reshape(len(pts), -1),
                              np.concatenate([e["points"].reshape(len(e["points"]), -1) for e in episodes]))
    # The sloppy `is_last` of one episode is reported, not fatal.
    plan = run_chunkc("plan", spec).stdout + run_chunkc("plan", spec).stderr
    assert "is_last" in plan and "1 of 4 episodes" in plan, plan
    del proc


def test_a_missing_path_lists_the_declared_ones_and_fps_is_required(tmp_path):
    channels = dict(BRIDGE_CHANNELS, action="steps/actoin")
    proc = run_chunkc("check", rlds_spec(tmp_path, BRIDGE, channels, '[profiles.act]\npreset = "act"\n'), check=False)
    assert proc.returncode != 0
    assert "steps/actoin" in proc.stderr and "steps/observation/image_3" in proc.stderr
    assert "episode_metadata/file_path" in proc.stderr and "did you mean `steps/action`" in proc.stderr
    assert "spec.toml:" in proc.stderr  # the spec key's line
    proc = run_chunkc("check", rlds_spec(tmp_path, BRIDGE, BRIDGE_CHANNELS, '[profiles.act]\npreset = "act"\n',
                                         fps=None), check=False)
    assert proc.returncode != 0 and "source.fps" in proc.stderr and "rlds" in proc.stderr, proc.stderr
    proc = run_chunkc("check", rlds_spec(tmp_path, BRIDGE, dict(BRIDGE_CHANNELS, **{
        "observation.task": "steps/language_instruction"}), '[profiles.act]\npreset = "act"\n'), check=False)
    assert proc.returncode != 0 and "task" in proc.stderr


# --- bad input ---------------------------------------------------------------------------------

def broken_copy(tmp_path, how):
    root = tmp_path / "bridge_dataset"
    shutil.copytree(BRIDGE, root)
    version = root / "1.0.0"
    for p in version.iterdir():
        p.chmod(0o644)
    train = version / "bridge_dataset-train.tfrecord-00000-of-00001"
    data = bytearray(train.read_bytes())
    offsets, at = [], 0
    while at < len(data):
        (n,) = struct.unpack("<Q", data[at:at + 8])
        offsets.append(at)
        at += 16 + n
    if how == "flip":
        data[offsets[3] + 12 + 100] ^= 0x10  # a byte inside record 3's data
        train.write_bytes(bytes(data))
        return root, f"record 3 at byte offset {offsets[3]}"
    if how == "truncate":
        train.write_bytes(bytes(data[: offsets[5] + 40]))
        return root, "truncated"
    if how == "features":
        f = json.loads((version / "features.json").read_text())
        action = f["featuresDict"]["features"]["steps"]["sequence"]["feature"]["featuresDict"]["features"]["action"]
        action["tensor"]["shape"]["dimensions"] = ["6"]
        (version / "features.json").write_text(json.dumps(f))
        return root, "steps/action"
    if how == "missing":
        (version / "bridge_dataset-val.tfrecord-00000-of-00001").unlink()
        return root, "bridge_dataset-val.tfrecord-00000-of-00001"
    raise ValueError(how)


@pytest.mark.parametrize("how", ["flip", "truncate", "features", "missing"])
def test_bad_input_fails_clearly_and_leaves_nothing(tmp_path, how):
    root, words = broken_copy(tmp_path, how)
    spec = rlds_spec(tmp_path, root, BRIDGE_CHANNELS, '[profiles.act]\npreset = "act"\nfps = 5\nchunk = 4\n')
    proc = run_chunkc("build", "-q", spec, check=False)
    assert proc.returncode != 0
    assert words in proc.stderr, proc.stderr
    if how == "flip":
        assert "checksum" in proc.stderr and "bridge_dataset-train.tfrecord-00000-of-00001" in proc.stderr
    if how == "features":
        assert "features.json" in proc.stderr
    if how == "missing":
        assert "dataset_info.json" in proc.stderr and "missing" in proc.stderr
    out = tmp_path / "out"
    assert not out.exists() or not any(p.is_file() and p.name != ".chunkc.build.lock" for p in out.rglob("*")), \
        list(out.rglob("*"))


# --- chunkc synth --format rlds ----------------------------------------------------------------

def test_synth_rlds_is_deterministic_and_reads_back(tmp_path):
    import h5py

    args = ["--format", "rlds", "--episodes", "70", "--steps", "12", "--cameras", "2",
            "--resolution", "32x40", "--action-dim", "4", "--state-dim", "3", "--fps", "10"]
    run_chunkc("synth", *args, tmp_path / "a")
    run_chunkc("synth", *args, tmp_path / "b")
    files = sorted(p.relative_to(tmp_path / "a") for p in (tmp_path / "a").rglob("*") if p.is_file())
    assert any("-of-00002" in str(p) for p in files)  # 70 episodes: two shards
    for p in files:
        assert (tmp_path / "a" / p).read_bytes() == (tmp_path / "b" / p).read_bytes(), p
    version = tmp_path / "a" / "rlds" / "1.0.0"
    keys = ["steps/action", "steps/observation/state", "steps/observation/cam0", "steps/observation/cam1"]
    episodes = read_split(version, "train", keys)
    assert len(episodes) == 70 and episodes[0]["task"]
    spec = tmp_path / "a" / "spec.toml"
    text = spec.read_text().replace('format = "hdf5"\n', 'format = "hdf5"\nnormalize = { action = "none", '
                                    '"observation.state" = "none" }\n')
    spec.write_text(text)
    run_chunkc("build", "-q", spec)
    with h5py.File(tmp_path / "a" / "out" / "act" / "data.h5") as f:
        meta = json.loads((tmp_path / "a" / "out" / "act" / "meta.json").read_text())
        order = meta["episodes"]
        assert np.array_equal(f["data/action"][:], np.concatenate([episodes[e]["steps/action"] for e in order]))
        for c in (0, 1):
            got = f[f"data/observation.cam{c}"][:]
            assert np.array_equal(got, np.concatenate([episodes[e][f"steps/observation/cam{c}"] for e in order]))
