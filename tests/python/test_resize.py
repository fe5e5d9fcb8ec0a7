"""Cameras resized at build time (`[profiles.<name>.cameras."<channel>"] size = [H, W]`), as
Diffusion Policy's `get_image_transform` resizes them: scale to cover the output keeping the
aspect ratio (OpenCV INTER_AREA when shrinking, INTER_LINEAR when enlarging), then crop the
centre. Every stored frame is compared with OpenCV's own `cv2.resize` + crop of the frames as
chunkc reads them (a profile without resize stores those), and the stored image statistics with
numpy's over the stored frames; the shapes every output declares are the stored ones; bad sizes,
bad camera names and forbidden enlargements are errors naming the key, with nothing written."""

import json
import math

import h5py
import numpy as np
import pytest

from conftest import REPO, load_dataset, run_chunkc

cv2 = pytest.importorskip("cv2")

SOURCE = REPO / "tests" / "data" / "aloha_sim_jpeg"  # 48x64 JPEG frames, two cameras
TOP, WRIST = "observation.images.top", "observation.images.left_wrist"
CAMS = {TOP: "top", WRIST: "left_wrist"}

# (profile, format, {channel: (H, W)}, upscale)
RESIZED = {
    # Whole factor 2 (a box average) and 4/3 (a weighted area average).
    "down": ("hdf5", {TOP: (24, 32), WRIST: (36, 48)}, False),
    # Not the source's aspect: covered at 30x40 (factor 1.6), 5 columns cropped each side; and
    # a wider output, covered at 30x40 with 5 rows cropped above and below.
    "crop": ("hdf5", {TOP: (30, 30), WRIST: (20, 40)}, False),
    # The same sizes through the zarr and LeRobot writers (their metadata is checked).
    "crop_zarr": ("zarr", {TOP: (30, 30)}, False),
    "crop_parquet": ("parquet", {TOP: (30, 30)}, False),
    # Enlarged: covered at 75x100 (bilinear), 5 rows cropped above and below.
    "up": ("hdf5", {TOP: (65, 100)}, True),
}


def spec_text(profiles: str) -> str:
    channels = "\n".join(f'"{c}" = "observations/images/{k}"' for c, k in CAMS.items())
    return (f'version = 1\n[source]\nformat = "aloha_hdf5"\npath = "{SOURCE}"\n'
            f'[source.channels]\naction = "action"\n"observation.qpos" = "observations/qpos"\n'
            f'{channels}\n[split]\nval_fraction = 0.34\nseed = 0\n[output]\ndir = "out"\n{profiles}')


def profile_text(name, fmt, cameras, upscale):
    text = f'\n[profiles.{name}]\npreset = "act"\nchunk = 4\nformat = "{fmt}"\n'
    for channel, (h, w) in cameras.items():
        text += f'[profiles.{name}.cameras."{channel}"]\nsize = [{h}, {w}]\n'
        if upscale:
            text += "upscale = true\n"
    return text


def dp_transform(frame, out_h, out_w):
    """diffusion_policy/common/cv2_util.py `get_image_transform`, with OpenCV itself."""
    ih, iw = frame.shape[:2]
    if iw / ih >= out_w / out_h:
        rh, rw = out_h, math.ceil(out_h / ih * iw)
        interp = cv2.INTER_LINEAR if out_h > ih else cv2.INTER_AREA
    else:
        rw, rh = out_w, math.ceil(out_w / iw * ih)
        interp = cv2.INTER_LINEAR if out_w > iw else cv2.INTER_AREA
    scaled = cv2.resize(frame, (rw, rh), interpolation=interp)
    top, left = (rh - out_h) // 2, (rw - out_w) // 2
    return scaled[top:top + out_h, left:left + out_w]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("resize")
    profiles = '\n[profiles.source]\npreset = "act"\nchunk = 4\n'
    profiles += "".join(profile_text(n, *v) for n, v in RESIZED.items())
    spec = d / "spec.toml"
    spec.write_text(spec_text(profiles))
    run_chunkc("build", "-q", "-j", "2", spec)
    return d


def stored(root, channel):
    with h5py.File(root / "data.h5", "r") as f:
        return f[f"data/{channel}"][:], f["meta/episode_ids"][:], f["meta/episode_ends"][:]


@pytest.mark.parametrize("profile", ["down", "crop", "up"])
def test_every_frame_is_opencvs_resize_and_crop(built, profile):
    _, cameras, _ = RESIZED[profile]
    worst = 0
    for channel, (h, w) in cameras.items():
        source, _, _ = stored(built / "out" / "source", channel)
        frames, _, _ = stored(built / "out" / profile, channel)
        assert frames.shape == (len(source), h, w, 3)
        want = np.stack([dp_transform(f, h, w) for f in source])
        diff = np.abs(frames.astype(np.int16) - want.astype(np.int16))
        worst = max(worst, int(diff.max()))
        assert diff.max() <= 1, (profile, channel, diff.max())
    print(f"{profile}: max abs diff vs cv2.resize + crop = {worst}")


# Real camera frames (Push-T's renders): raw in Diffusion Policy's zarr, and the same frames as
# H.264 video in a LeRobot v2.1 dataset (decoded by chunkc, feature `video`).
REAL = {
    "pusht_zarr": ('format = "diffusion_policy_zarr"\npath = "{}"\nfps = 10\n'
                   '[source.channels]\naction = "action"\n"observation.image" = "img"',
                   REPO / "tests" / "data" / "pusht_subset.zarr", "observation.image"),
    "lerobot_video": ('format = "lerobot"\npath = "{}"\n[source.channels]\naction = "action"\n'
                      '"observation.images.top" = "observation.images.top"',
                      REPO / "tests" / "data" / "lerobot_video_v21", "observation.images.top"),
}


@pytest.mark.parametrize("source", list(REAL))
def test_real_camera_frames_equal_opencvs(tmp_path, source):
    text, path, channel = REAL[source]
    # 96x96 to 84x84 (a weighted area average), to 64x80 (covered at 80x80, 8 rows cropped
    # above and below) and to 120x100 (enlarged to 120x120, 10 columns cropped each side).
    sizes = {"square": ((84, 84), False), "crop": ((64, 80), False), "up": ((120, 100), True)}
    profiles = '\n[profiles.source]\npreset = "act"\nfps = 10\nchunk = 4\n'
    for name, ((h, w), upscale) in sizes.items():
        profiles += (f'\n[profiles.{name}]\npreset = "act"\nfps = 10\nchunk = 4\n'
                     f'[profiles.{name}.cameras."{channel}"]\nsize = [{h}, {w}]\n'
                     + ("upscale = true\n" if upscale else ""))
    spec = tmp_path / "spec.toml"
    spec.write_text(f'version = 1\n[source]\n{text.format(path)}\n[split]\nval_fraction = 0.2\n'
                    f'seed = 0\n[output]\ndir = "out"\n{profiles}')
    proc = run_chunkc("build", "-q", spec, check=False)
    if "without the `video` feature" in proc.stderr:
        pytest.skip("the chunkc binary lacks the `video` feature")
    assert proc.returncode == 0, proc.stderr
    source_frames, _, _ = stored(tmp_path / "out" / "source", channel)
    for name, ((h, w), _) in sizes.items():
        frames, _, _ = stored(tmp_path / "out" / name, channel)
        want = np.stack([dp_transform(f, h, w) for f in source_frames])
        diff = np.abs(frames.astype(np.int16) - want.astype(np.int16))
        print(f"{source} {name}: {len(frames)} frames, max abs diff vs cv2 = {diff.max()}")
        assert diff.max() <= 1, (source, name, diff.max())


def test_image_stats_describe_the_stored_frames(built):
    for profile in ("down", "crop", "up"):
        root = built / "out" / profile
        meta = json.loads((root / "meta.json").read_text())
        stats = json.loads((root / "stats.json").read_text())
        train = set(meta["split"]["train"])
        for channel in RESIZED[profile][1]:
            frames, ids, ends = stored(root, channel)
            starts = np.concatenate([[0], ends[:-1]])
            px = np.concatenate([frames[a:b] for e, a, b in zip(ids, starts, ends) if e in train])
            s = stats[channel]
            assert s["count"] == len(px)
            px = px.reshape(-1, 3).astype(np.float64)
            np.testing.assert_allclose(s["mean"], px.mean(axis=0), rtol=1e-6)
            np.testing.assert_allclose(s["std"], px.std(axis=0), rtol=1e-6)
            np.testing.assert_allclose(s["min"], px.min(axis=0))
            np.testing.assert_allclose(s["max"], px.max(axis=0))
            np.testing.assert_allclose(s["p001"], np.percentile(px, 0.1, axis=0), rtol=1e-6)
            np.testing.assert_allclose(s["p999"], np.percentile(px, 99.9, axis=0), rtol=1e-6)


def test_every_output_declares_the_stored_shape(built):
    out = built / "out"
    # chunkc's HDF5 and its loader.
    with h5py.File(out / "crop" / "data.h5", "r") as f:
        assert f[f"data/{TOP}"].shape[1:] == (30, 30, 3)
        assert f[f"data/{TOP}"].chunks == (1, 30, 30, 3)
        assert f[f"data/{WRIST}"].shape[1:] == (20, 40, 3)
    sample = load_dataset(out / "crop")[0]
    assert sample[TOP].shape[-3:] == (30, 30, 3)
    assert sample[WRIST].shape[-3:] == (20, 40, 3)
    # Zarr: the frames array and its chunks, and the frames themselves equal the HDF5 profile's.
    zarray = json.loads((out / "crop_zarr" / "data.zarr" / "data" / "top" / ".zarray").read_text())
    assert zarray["shape"][1:] == [30, 30, 3] and zarray["chunks"][1:] == [30, 30, 3]
    zarr = pytest.importorskip("zarr")
    hdf5_top, _, _ = stored(out / "crop", TOP)
    np.testing.assert_array_equal(zarr.open(str(out / "crop_zarr" / "data.zarr"), mode="r")["data/top"][:],
                                  hdf5_top)
    # LeRobot's info.json.
    info = json.loads((out / "crop_parquet" / "meta" / "info.json").read_text())
    assert info["features"][TOP]["shape"] == [30, 30, 3]
    assert info["features"][WRIST]["shape"] == [48, 64, 3]
    # meta.json's channels, when it lists them, and the plan.
    plan = json.loads(run_chunkc("plan", "--format", "json", built / "spec.toml").stdout)
    channels = {p["name"]: {c["name"]: c for c in p["channels"]} for p in plan["profiles"]}
    assert channels["crop"][TOP]["shape"] == [30, 30, 3]
    assert channels["crop"][TOP]["resize"] == {"from": [48, 64], "size": [30, 30],
                                               "scaled": [30, 40], "method": "area"}
    assert channels["up"][TOP]["resize"]["method"] == "linear"
    assert "resize" not in channels["source"][TOP]
    text = run_chunkc("plan", built / "spec.toml").stdout
    assert "48x64 -> 30x30 (area to 30x40, centre crop)" in text


def test_estimates_count_the_stored_frames(tmp_path):
    """`chunkc plan`'s estimate of the data file shrinks with the frames."""
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text('\n[profiles.full]\npreset = "act"\nchunk = 4\n'
                              + profile_text("small", "hdf5", {TOP: (24, 32), WRIST: (24, 32)}, False)))
    plan = json.loads(run_chunkc("plan", "--format", "json", spec).stdout)
    size = {p["name"]: p["files"][0]["estimated_bytes"] for p in plan["profiles"]}
    steps = plan["profiles"][0]["steps"]
    assert size["full"] - size["small"] == steps * 2 * 3 * (48 * 64 - 24 * 32)


def test_the_same_bytes_with_any_thread_count(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(profile_text("crop", *RESIZED["crop"])))
    data = {}
    for threads in ("1", "2"):
        (tmp_path / "chunkc.lock").unlink(missing_ok=True)
        run_chunkc("build", "-q", "-j", threads, spec)
        data[threads] = (tmp_path / "out" / "crop" / "data.h5").read_bytes()
    assert data["1"] == data["2"]


def test_shards_merge_into_the_same_bytes(tmp_path):
    """Two profiles at one rate storing a camera at two sizes (two rate jobs), built whole and
    as two shards merged."""
    profiles = (profile_text("crop", *RESIZED["crop"])
                + profile_text("down", *RESIZED["down"]))
    files = {}
    for how in ("single", "sharded"):
        d = tmp_path / how
        d.mkdir()
        spec = d / "spec.toml"
        spec.write_text(spec_text(profiles))
        if how == "single":
            run_chunkc("build", "-q", spec)
        else:
            for i in range(2):
                run_chunkc("build", "-q", "--shard", f"{i}/2", "--partials", d / "parts", spec)
            run_chunkc("merge", "-q", "--partials", d / "parts", spec)
        files[how] = {p: (d / "out" / p / "data.h5").read_bytes() for p in ("crop", "down")}
    assert files["single"] == files["sharded"]


KEY = 'profiles.bad.cameras."observation.images.top"'


@pytest.mark.parametrize("camera, size, extra, message", [
    # Enlarging without `upscale`: both sizes named.
    (TOP, "[96, 64]", "", f"`{KEY}.size` = [96, 64] is larger than the source's "
                          f"`{TOP}` frames, [48, 64] (H, W)"),
    (TOP, "[40, 80]", "upscale = false", f"`{KEY}.size` = [40, 80] is larger"),
    # Not an image channel of the source, or not a channel at all.
    ("observation.qpos", "[8, 8]", "", 'names `observation.qpos`, which is a low-dimensional channel'),
    ("observation.images.topp", "[8, 8]", "",
     "`profiles.bad.cameras` names `observation.images.topp`, which is not a channel in `[source.channels]`"),
    # Malformed sizes.
    (TOP, "[0, 32]", "", f"`{KEY}.size` must be `[H, W]`, two positive integers (height, width), not `[0, 32]`"),
    (TOP, "[-24, 32]", "", f"`{KEY}.size` must be `[H, W]`"),
    (TOP, "[24]", "", f"`{KEY}.size` must be `[H, W]`, two positive integers (height, width), not `[24]`"),
    (TOP, "[24, 32, 3]", "", f"`{KEY}.size` must be `[H, W]`"),
])
def test_bad_cameras_are_errors_naming_the_key(tmp_path, camera, size, extra, message):
    text = f'\n[profiles.bad]\npreset = "act"\nchunk = 4\n[profiles.bad.cameras."{camera}"]\nsize = {size}\n{extra}\n'
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(text))
    for command in ("build", "plan"):
        proc = run_chunkc(command, spec, check=False)
        assert proc.returncode != 0
        assert message in proc.stderr, proc.stderr
        assert "-->" in proc.stderr and "spec.toml:" in proc.stderr, proc.stderr
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    assert not (tmp_path / "chunkc.lock").exists()


def test_every_writer_stores_the_resized_frames(tmp_path):
    """ACT's episode files, robomimic's demos and LeRobot's PNGs hold exactly the frames of the
    HDF5 profile (which equal OpenCV's, above), read with h5py, pyarrow and Pillow."""
    import glob
    import io

    pq = pytest.importorskip("pyarrow.parquet")
    Image = pytest.importorskip("PIL.Image")
    cameras = {TOP: (30, 30), WRIST: (20, 40)}
    formats = {"h": "hdf5", "a": "act_episodes", "r": "robomimic_hdf5", "p": "parquet"}
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text("".join(profile_text(n, f, cameras, False) for n, f in formats.items())))
    run_chunkc("build", "-q", spec)
    out = tmp_path / "out"
    for channel, key in CAMS.items():
        want, _, _ = stored(out / "h", channel)
        assert want.shape[1:3] == cameras[channel]
        act = [h5py.File(out / "a" / f"episode_{i}.hdf5", "r")[f"observations/images/{key}"][:]
               for i in range(len(glob.glob(str(out / "a" / "episode_*.hdf5"))))]
        np.testing.assert_array_equal(np.concatenate(act), want)
        with h5py.File(out / "r" / "data.hdf5", "r") as f:
            demos = sorted(f["data"], key=lambda d: int(d.split("_")[1]))
            np.testing.assert_array_equal(np.concatenate([f[f"data/{d}/obs/{key}"][:] for d in demos]), want)
        rows = pq.read_table(sorted(glob.glob(str(out / "p" / "data" / "*" / "*.parquet")))[0]).to_pandas()
        png = np.stack([np.asarray(Image.open(io.BytesIO(x["bytes"]))) for x in rows[channel]])
        np.testing.assert_array_equal(png, want)
