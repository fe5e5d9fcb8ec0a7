"""The generated loader's action transforms (issue 38), against independent oracles.

A synthetic Diffusion Policy replay buffer is built into a `format = "zarr"` profile (raw values
stored), and its meta.json is then patched with a "transforms" list, each transformed channel's
"transformed_shape" and a z-score "normalization" computed here over the oracle's own transformed
windows. The loader's samples are checked against
- scipy.spatial.transform.Rotation for every rotation kind both ways (6D rows as pytorch3d's
  `matrix_to_rotation_6d`, columns as Zhou et al.), all 24 euler conventions;
- openpi's DeltaActions written in numpy (one current state for the whole chunk; the ALOHA mask
  (6, -1, 6, -1) and DROID's (7, -1); edge-padded chunks at an episode's end);
- UMI's relative pose (inv(T_base) @ T, then position + rot6d rows);
and `ds.to_source` must give back the source values (within 1e-5).

The profiles are built with the repository's loader templates as a template override, rendered
with every part (conftest.every_part_templates: the profiles built have no transforms, and their
own loaders hold no transform code), so these tests check those files whatever binary is at hand
(the embedded copies are the same files).
"""

import json
import shutil
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import every_part_templates, load_dataset, make_replay_buffer, run_chunkc, write_spec

LENGTHS = (23, 9, 31, 17, 12)
K = 8
OBS = 2
KINDS = {"axis_angle": 3, "quaternion_wxyz": 4, "quaternion_xyzw": 4, "euler": 3, "matrix": 9,
         "rotation_6d_rows": 6, "rotation_6d_columns": 6}
# Every axis sequence scipy takes: Tait-Bryan and proper, extrinsic (lowercase) and intrinsic.
SEQS = ["xyz", "xzy", "yxz", "yzx", "zxy", "zyx", "xyx", "xzx", "yxy", "yzy", "zxz", "zyz"]
CONVENTIONS = SEQS + [s.upper() for s in SEQS]
EULER = "ZYX"  # the convention the stored euler channel is read with (any works: see _euler)


# --- oracles -------------------------------------------------------------------------------------

def rot6d_to_matrix(d6):
    """pytorch3d `rotation_6d_to_matrix`: Gram-Schmidt of the two rows."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = a1 / np.linalg.norm(a1, axis=-1, keepdims=True)
    b2 = a2 - (b1 * a2).sum(-1, keepdims=True) * b1
    b2 = b2 / np.linalg.norm(b2, axis=-1, keepdims=True)
    return np.stack([b1, b2, np.cross(b1, b2)], axis=-2)


def to_rotation(kind, x, convention=None):
    """scipy Rotation of values of `kind` (KINDS' names: rotation_6d with its layout)."""
    x = np.asarray(x, dtype=np.float64)
    if kind == "axis_angle":
        return Rotation.from_rotvec(x)
    if kind == "quaternion_wxyz":
        return Rotation.from_quat(x, scalar_first=True)
    if kind == "quaternion_xyzw":
        return Rotation.from_quat(x)
    if kind == "euler":
        return Rotation.from_euler(convention, x)
    if kind == "matrix":
        return Rotation.from_matrix(x.reshape(x.shape[:-1] + (3, 3)))
    m = rot6d_to_matrix(x)
    return Rotation.from_matrix(m if kind == "rotation_6d_rows" else np.swapaxes(m, -1, -2))


def from_rotation(kind, r, convention=None):
    if kind == "axis_angle":
        return r.as_rotvec()
    if kind == "quaternion_wxyz":
        return r.as_quat(canonical=True, scalar_first=True)
    if kind == "quaternion_xyzw":
        return r.as_quat(canonical=True)
    if kind == "euler":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # gimbal lock: scipy sets the third angle to 0
            return r.as_euler(convention)
    m = r.as_matrix()
    if kind == "matrix":
        return m.reshape(m.shape[:-2] + (9,))
    if kind == "rotation_6d_rows":  # pytorch3d matrix_to_rotation_6d
        return m[..., :2, :].reshape(m.shape[:-2] + (6,))
    return np.swapaxes(m, -1, -2)[..., :2, :].reshape(m.shape[:-2] + (6,))  # [R00, R10, R20, R01, R11, R21]


def make_bool_mask(*dims):
    """openpi `transforms.make_bool_mask`."""
    out = []
    for d in dims:
        out.extend([True] * d if d > 0 else [False] * -d)
    return tuple(out)


def delta_actions(actions, state, mask):
    """openpi `DeltaActions`: one current state for the whole chunk."""
    mask = np.asarray(mask)
    dims = mask.shape[-1]
    actions = actions.copy()
    actions[..., :dims] -= np.expand_dims(np.where(mask, state[..., :dims], 0), axis=-2)
    return actions


def pose_to_mat(pose):
    """UMI `pose_util.pose_to_mat`: position + rotation vector -> 4x4."""
    mat = np.zeros(pose.shape[:-1] + (4, 4))
    mat[..., :3, :3] = Rotation.from_rotvec(pose[..., 3:6].reshape(-1, 3)).as_matrix().reshape(pose.shape[:-1] + (3, 3))
    mat[..., :3, 3] = pose[..., :3]
    mat[..., 3, 3] = 1
    return mat


def umi_relative(pose, base):
    """UMI `convert_pose_mat_rep(..., pose_rep="relative")` then `mat_to_pose10d` (rot6d rows)."""
    rel = np.linalg.inv(pose_to_mat(base))[..., None, :, :] @ pose_to_mat(pose)
    return np.concatenate([rel[..., :3, 3], rel[..., :2, :3].reshape(rel.shape[:-2] + (6,))], axis=-1)


# --- the synthetic source --------------------------------------------------------------------------

def random_rotations(n, rng):
    """Random rotations with the hard cases mixed in: identity, angles of 1e-9 and 1e-5, angles
    within 1e-3 of pi (axis-angle values keep a definite sign there)."""
    r = Rotation.random(n, random_state=rng).as_rotvec()
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    special = rng.integers(0, 5, n)
    r[special == 0] = 0.0
    r[special == 1] = axes[special == 1] * 1e-9
    r[special == 2] = axes[special == 2] * 1e-5
    r[special == 3] = axes[special == 3] * (np.pi - 1e-3)
    return Rotation.from_rotvec(r)


def _euler(r):
    """Euler angles of EULER with the middle angle in (0.1, 1.4): canonical in every convention
    (Tait-Bryan [-pi/2, pi/2], proper [0, pi]), so that reading them back gives the same three."""
    rng = np.random.default_rng(7)
    n = len(r)
    return np.stack([rng.uniform(-3.1, 3.1, n), rng.uniform(0.1, 1.4, n), rng.uniform(-3.1, 3.1, n)], axis=1)


def episodes():
    rng = np.random.default_rng(38)
    out = []
    for n in LENGTHS:
        rot, base = random_rotations(n, rng), random_rotations(n, rng)
        pos, base_pos = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
        grip = rng.uniform(0, 1, (n, 1))
        ep = {
            "pose": np.concatenate([pos, rot.as_rotvec(), grip], axis=1),
            "eef": np.concatenate([base_pos, base.as_rotvec()], axis=1),
            "joints": rng.normal(size=(n, 14)) + np.arange(14),
            "qpos": rng.normal(size=(n, 14)) + np.arange(14),
        }
        for kind in KINDS:
            ep[kind] = from_rotation(kind, rot) if kind != "euler" else _euler(rot)
        # Unit quaternions with either sign of w, as sources hold them.
        flip = rng.random(n) < 0.5
        for kind in ("quaternion_wxyz", "quaternion_xyzw"):
            ep[kind] = np.where(flip[:, None], -ep[kind], ep[kind])
        out.append({k: v.astype(np.float32) for k, v in ep.items()})
    return out


PROFILE = f"""templates = "tpl"
[profiles.base]
chunk = {K}
obs_history = {OBS}
padding = "edge"
format = "zarr"
"""


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    d = tmp_path_factory.mktemp("transforms")
    eps = episodes()
    make_replay_buffer(d / "src.zarr", eps)
    every_part_templates(d)
    built = {}
    for name, channels in {
        "pose": {"action": "pose", "observation.eef_pose": "eef", "observation.state": "qpos",
                 **{f"observation.{k}": k for k in KINDS}},
        "joints": {"action": "joints", "observation.state": "qpos"},
    }.items():
        spec_dir = d / name
        spec_dir.mkdir()
        shutil.copytree(d / "tpl", spec_dir / "tpl")
        run_chunkc("build", "-q", write_spec(spec_dir, PROFILE, source=d / "src.zarr", channels=channels))
        built[name] = spec_dir / "out" / "base"
    return {"dir": d, "episodes": eps, "built": built}


# --- windows as the loader reads them, computed independently -------------------------------------

def windows(meta, split="train"):
    """(episode id, t, action steps clamped into the episode, padding mask, observation steps)
    for every sample of the split: stride 1, actions from t (alignment current), edge padding."""
    out = []
    for e in meta["split"][split]:
        n = LENGTHS[e]
        for t in range(n):
            steps = t + np.arange(K)
            out.append((e, t, np.clip(steps, 0, n - 1), steps >= n, np.maximum(t + np.arange(1 - OBS, 1), 0)))
    return out


def patch(built, tmp, name, transforms, oracle):
    """A copy of profile `built` whose meta.json has `transforms`; `oracle(channel, episode, rows,
    t)` gives a channel's transformed raw rows. Each transformed channel's normalization is a
    z-score over the oracle's training windows (the K action rows or the observation rows)."""
    dst = tmp / name
    shutil.copytree(built, dst)
    meta = json.loads((dst / "meta.json").read_text())
    meta["transforms"] = transforms
    meta["stats_population"] = "windows"
    for channel in sorted({op["channel"] for op in transforms}):
        rows = np.concatenate([oracle(channel, e, a if channel == "action" else o, t)
                               for e, t, a, _, o in windows(meta)])
        meta["channels"][channel]["transformed_shape"] = [rows.shape[1]]
        meta["normalization"][channel] = {"mode": "zscore", "center": rows.mean(0).tolist(),
                                          "scale": (rows.std(0) + 1e-6).tolist(), "clip": False}
    (dst / "meta.json").write_text(json.dumps(meta, indent=2))
    return dst, meta


def check(root, meta, oracle, source_of, split="train", atol=2e-5):
    """Every sample of `split` against the oracle; `to_source` back to the source rows; the
    batch path equal to the per-item path; to_source on a stacked batch."""
    ds = load_dataset(root, split)
    cases = windows(meta, split)
    assert len(ds) == len(cases)
    transformed = sorted({op["channel"] for op in meta["transforms"]})
    samples = ds.__getitems__(list(range(len(ds))))
    for s, (e, t, a, pad, o) in zip(samples, cases):
        assert (s["episode_index"], s["frame_index"]) == (e, t)
        np.testing.assert_array_equal(s["action_is_pad"], pad)
        for channel in transformed:
            rows = a if channel == "action" else o
            norm = meta["normalization"][channel]
            want = (oracle(channel, e, rows, t) - np.asarray(norm["center"])) / np.asarray(norm["scale"])
            assert s[channel].dtype == np.float32 and s[channel].shape == want.shape
            np.testing.assert_allclose(s[channel], want, atol=atol, err_msg=f"{channel} e{e} t{t}")
            back = ds.to_source(channel, s[channel], s)
            assert back.dtype == np.float64
            source_of(channel, back, e, rows)
    for i in (0, len(ds) // 2, len(ds) - 1):
        one = ds[i]
        for key in one:
            np.testing.assert_array_equal(np.asarray(one[key]), np.asarray(samples[i][key]))
    # A batch as stacked by a collate function.
    batch = {k: np.stack([np.asarray(s[k]) for s in samples[:5]]) for k in samples[0]}
    for channel in transformed:
        stacked = ds.to_source(channel, batch[channel], batch)
        for j in range(5):
            np.testing.assert_allclose(stacked[j], ds.to_source(channel, samples[j][channel], samples[j]), atol=1e-12)
    return ds


def same_source(eps, key, kind=None, atol=1e-5):
    """`source_of` for channels stored from source key `key`: to_source equals its rows (quaternions
    up to sign, since q and -q are one rotation)."""
    def source_of(channel, back, e, rows):
        want = eps[e][key][rows].astype(np.float64)
        if kind in ("quaternion_wxyz", "quaternion_xyzw"):
            sign = np.where((back * want).sum(-1, keepdims=True) < 0, -1.0, 1.0)
            back = back * sign
        np.testing.assert_allclose(back, want, atol=atol, err_msg=f"to_source {channel} e{e}")
    return source_of


# --- tests -----------------------------------------------------------------------------------------

def loader_module(root):
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"loader_fns_{root.name}", root / "loader.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_rotation_conversions_match_scipy_both_ways(source):
    """The loader's numpy conversions against scipy, including identity, tiny angles, exactly pi
    and within 1e-7 of pi, for every kind and every euler convention."""
    L = loader_module(source["built"]["pose"])
    rng = np.random.default_rng(0)
    axes = rng.normal(size=(6, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    hard = np.concatenate([np.zeros((1, 3)), 1e-12 * axes, 1e-6 * axes, np.pi * np.eye(3), np.pi * axes,
                           (np.pi - 1e-7) * axes, -np.pi * np.eye(3)])
    r = Rotation.concatenate([Rotation.random(500, random_state=1), Rotation.from_rotvec(hard)])
    m = r.as_matrix()
    for kind in KINDS:
        name = "rotation_6d" if kind.startswith("rotation_6d") else kind
        layout = "columns" if kind == "rotation_6d_columns" else "rows"
        for convention in CONVENTIONS if kind == "euler" else [None]:
            x = from_rotation(kind, r, convention)
            np.testing.assert_allclose(L.rotation_to_matrix(x, name, layout, convention), m, atol=1e-6 if kind == "euler" else 1e-12)
            back = L.matrix_to_rotation(m, name, layout, convention)
            # The same rotation, whatever the representation's ambiguities.
            np.testing.assert_allclose(to_rotation(kind, back, convention).as_matrix(), m, atol=1e-6)
            if kind in ("quaternion_wxyz", "quaternion_xyzw"):
                assert (back[:, 0 if kind == "quaternion_wxyz" else 3] >= 0).all()
                np.testing.assert_allclose(np.linalg.norm(back, axis=1), 1, atol=1e-12)
            if kind == "axis_angle":
                assert (np.linalg.norm(back, axis=1) <= np.pi + 1e-12).all()
                definite = np.linalg.norm(x, axis=1) < np.pi - 1e-9
                np.testing.assert_allclose(back[definite], x[definite], atol=1e-9)
            elif kind == "euler":
                diff = np.angle(np.exp(1j * (back - x)))  # angles equal modulo 2 pi
                np.testing.assert_allclose(diff, 0, atol=1e-6, err_msg=convention)
            else:
                np.testing.assert_allclose(back, x, atol=1e-12)
    # Non-unit quaternions are normalized before use; leading axes are kept.
    q = r.as_quat(scalar_first=True)[:12].reshape(3, 4, 4)
    np.testing.assert_allclose(L.rotation_to_matrix(q * 1.005, "quaternion_wxyz"), m[:12].reshape(3, 4, 3, 3), atol=1e-12)


@pytest.mark.parametrize("frm", list(KINDS))
def test_rotation_transform_every_kind(source, tmp_path, frm):
    """A rotation transform from every kind to every kind `to` may be (not euler), on the
    observation history of a channel stored in `frm`; to_source gives the stored values back."""
    eps = source["episodes"]
    frm_name = "rotation_6d" if frm.startswith("rotation_6d") else frm
    from_layout = "columns" if frm == "rotation_6d_columns" else "rows"
    channel = f"observation.{frm}"
    for to in [k for k in KINDS if k != "euler"]:
        to_name = "rotation_6d" if to.startswith("rotation_6d") else to
        to_layout = "columns" if to == "rotation_6d_columns" else "rows"
        if frm_name == to_name == "rotation_6d" and from_layout != to_layout:
            continue  # one layout per transform
        layout = to_layout if to_name == "rotation_6d" else from_layout
        convention = EULER if frm == "euler" else None
        op = {"op": "rotation", "channel": channel, "dims": [0, KINDS[frm]], "from": frm_name, "to": to_name,
              "layout": layout, "convention": convention}

        def oracle(ch, e, rows, t):
            return from_rotation(to, to_rotation(frm, eps[e][frm][rows], convention))

        root, meta = patch(source["built"]["pose"], tmp_path, f"{frm}_to_{to}", [op], oracle)
        ds = check(root, meta, oracle, same_source(eps, frm, frm))
        # Rotation alone needs no reference: the per-step read path transforms too.
        rows = np.arange(ds.episode_ends[-1])
        norm = meta["normalization"][channel]
        want = (np.concatenate([oracle(channel, e, np.arange(n), 0) for e, n in enumerate(LENGTHS)])
                - norm["center"]) / np.asarray(norm["scale"])
        np.testing.assert_allclose(ds._read(channel, rows), want, atol=2e-5)


def test_dp_abs_action_rotation_on_action_chunks(source, tmp_path):
    """Diffusion Policy's abs_action: [pos, axis_angle, gripper] -> [pos, rot6d rows, gripper]
    (7 -> 10) on the K action rows, edge padding included; uncached reads agree."""
    eps = source["episodes"]
    op = {"op": "rotation", "channel": "action", "dims": [3, 6], "from": "axis_angle", "to": "rotation_6d",
          "layout": "rows", "convention": None}

    def oracle(ch, e, rows, t):
        p = eps[e]["pose"][rows].astype(np.float64)
        return np.concatenate([p[:, :3], from_rotation("rotation_6d_rows", Rotation.from_rotvec(p[:, 3:6])), p[:, 6:]], axis=1)

    root, meta = patch(source["built"]["pose"], tmp_path, "abs_action", [op], oracle)
    ds = check(root, meta, oracle, same_source(eps, "pose"))
    assert ds[0]["action"].shape == (K, 10)
    uncached = loader_module(root).ChunkedDataset(str(root), "train", cache_lowdim=False)
    for i in (0, 7, len(ds) - 1):
        np.testing.assert_array_equal(uncached[i]["action"], ds[i]["action"])


@pytest.mark.parametrize("dims", [(6, -1, 6, -1), (7, -1)], ids=["aloha", "droid"])
@pytest.mark.parametrize("split", ["train", "val"])
def test_delta_actions_as_openpi(source, tmp_path, dims, split):
    """openpi DeltaActions: the current state (frame_index) subtracted from the whole chunk where
    the mask holds, the dims past the mask untouched; the edge-padded rows at an episode's end are
    the last action minus the same current state."""
    eps = source["episodes"]
    mask = make_bool_mask(*dims)
    op = {"op": "delta", "channel": "action", "reference": "observation.state", "mask": list(mask)}

    def oracle(ch, e, rows, t):
        return delta_actions(eps[e]["joints"][rows].astype(np.float64), eps[e]["qpos"][t].astype(np.float64), mask)

    root, meta = patch(source["built"]["joints"], tmp_path, f"delta_{len(mask)}", [op], oracle)
    ds = check(root, meta, oracle, same_source(eps, "joints"), split=split)
    # The observation is not transformed; the padded rows repeat the last transformed row.
    s = ds[len(ds) - 1]
    assert s["action_is_pad"][1:].all()
    np.testing.assert_array_equal(s["action"][1:], np.repeat(s["action"][:1], K - 1, axis=0))
    if split == "train":
        # "windows" statistics: the normalized population is z-scored exactly.
        y = ds._population("action").astype(np.float64)
        assert len(y) == len(ds) * K
        np.testing.assert_allclose(y.mean(0), 0, atol=1e-5)
        np.testing.assert_allclose(y.std(0), 1, atol=1e-4)


def test_relative_pose_as_umi(source, tmp_path):
    """UMI's relative action: inv(T_base) @ T with base the current end-effector pose, written
    as position + rot6d rows + gripper (10); the observation history of the pose relative to
    the same base."""
    eps = source["episodes"]
    ops = [
        {"op": "relative_pose", "channel": "action", "dims": [0, 6], "rotation": "axis_angle",
         "reference": "observation.eef_pose", "reference_dims": [0, 6], "reference_rotation": "axis_angle",
         "to": "rotation_6d", "layout": "rows", "convention": None},
        {"op": "relative_pose", "channel": "observation.eef_pose", "dims": [0, 6], "rotation": "axis_angle",
         "reference": "observation.eef_pose", "reference_dims": [0, 6], "reference_rotation": "axis_angle",
         "to": "rotation_6d", "layout": "rows", "convention": None},
    ]

    def oracle(ch, e, rows, t):
        base = eps[e]["eef"][t].astype(np.float64)
        if ch == "action":
            p = eps[e]["pose"][rows].astype(np.float64)
            return np.concatenate([umi_relative(p[:, :6], base), p[:, 6:]], axis=1)
        return umi_relative(eps[e]["eef"][rows].astype(np.float64), base)

    root, meta = patch(source["built"]["pose"], tmp_path, "umi", ops, oracle)
    keys = {"action": "pose", "observation.eef_pose": "eef"}

    def source_of(channel, back, e, rows):
        same_source(eps, keys[channel])(channel, back, e, rows)

    ds = check(root, meta, oracle, source_of)
    s = ds[5]
    assert s["action"].shape == (K, 10) and s["observation.eef_pose"].shape == (OBS, 9)
    # The current pose relative to itself is the identity (normalized).
    norm = meta["normalization"]["observation.eef_pose"]
    identity = (np.array([0, 0, 0, 1, 0, 0, 0, 1, 0]) - np.asarray(norm["center"])) / np.asarray(norm["scale"])
    np.testing.assert_allclose(s["observation.eef_pose"][-1], identity, atol=1e-4)


def test_chained_transforms_index_the_values_before_each(source, tmp_path):
    """rotation (axis_angle -> quaternion_xyzw, 7 -> 8), then relative_pose over the new dims
    [0, 7) into a matrix (8 -> 13), then delta on the position with the raw state: each op's dims
    index the values left by the ops before it; to_source undoes them in reverse order."""
    eps = source["episodes"]
    ops = [
        {"op": "rotation", "channel": "action", "dims": [3, 6], "from": "axis_angle", "to": "quaternion_xyzw",
         "layout": "rows", "convention": None},
        {"op": "relative_pose", "channel": "action", "dims": [0, 7], "rotation": "quaternion_xyzw",
         "reference": "observation.eef_pose", "reference_dims": [0, 6], "reference_rotation": "axis_angle",
         "to": "matrix", "layout": "rows", "convention": None},
        {"op": "delta", "channel": "action", "reference": "observation.state", "mask": [True, False, True]},
    ]

    def oracle(ch, e, rows, t):
        p = eps[e]["pose"][rows].astype(np.float64)
        base = pose_to_mat(eps[e]["eef"][t].astype(np.float64))
        rel = np.linalg.inv(base) @ pose_to_mat(p[:, :6])
        x = np.concatenate([rel[:, :3, 3], rel[:, :3, :3].reshape(-1, 9), p[:, 6:]], axis=1)
        return delta_actions(x, eps[e]["qpos"][t].astype(np.float64), [True, False, True])

    root, meta = patch(source["built"]["pose"], tmp_path, "chain", ops, oracle)
    check(root, meta, oracle, same_source(eps, "pose"))


@pytest.mark.parametrize("padding", ["zero", "mask"])
def test_padding_after_transforms(source, tmp_path, padding):
    """zero padding is normalize(zeros of the transformed width), mask padding 0 normalized;
    the rows before the episode's end are transformed as with edge padding."""
    eps = source["episodes"]
    op = {"op": "delta", "channel": "action", "reference": "observation.state", "mask": list(make_bool_mask(6, -1, 6, -1))}

    def oracle(ch, e, rows, t):
        return delta_actions(eps[e]["joints"][rows].astype(np.float64), eps[e]["qpos"][t].astype(np.float64),
                             op["mask"])

    root, meta = patch(source["built"]["joints"], tmp_path, f"pad_{padding}", [op], oracle)
    edge = load_dataset(root)
    meta["padding"] = padding
    (root / "meta.json").write_text(json.dumps(meta))
    ds = load_dataset(root)
    norm = meta["normalization"]["action"]
    zero = -np.asarray(norm["center"]) / np.asarray(norm["scale"]) if padding == "zero" else np.zeros(14)
    for i in range(len(ds)):
        s, e = ds[i], edge[i]
        pad = s["action_is_pad"]
        np.testing.assert_array_equal(s["action"][~pad], e["action"][~pad])
        np.testing.assert_allclose(s["action"][pad], np.broadcast_to(zero, (int(pad.sum()), 14)), atol=1e-6)


def test_without_transforms_to_source_is_denormalize(source):
    ds = load_dataset(source["built"]["joints"])
    s = ds[3]
    np.testing.assert_array_equal(ds.to_source("action", s["action"], s), ds.denormalize("action", s["action"]))
