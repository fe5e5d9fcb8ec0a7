"""Independent numpy implementations of what a chunkc profile should contain.

Nothing here imports chunkc code or its generated loader: windows, padding and normalization are
recomputed from the documented definitions, straight from the raw source arrays.
"""

import numpy as np


def norm_params(mode, train_values):
    """(center, scale, clip) for `mode`, from all training timesteps (rows) of one channel."""
    x = np.asarray(train_values, dtype=np.float64)
    dims = x.shape[1]
    if mode == "none":
        return np.zeros(dims), np.ones(dims), False
    if mode == "zscore":
        # ACT: unbiased std, clipped to at least 1e-2.
        return x.mean(axis=0), np.maximum(x.std(axis=0, ddof=1), 1e-2), False
    if mode == "minmax":
        lo = np.percentile(x, 0.1, axis=0)
        hi = np.percentile(x, 99.9, axis=0)
        center = (lo + hi) / 2
        scale = np.where(hi - lo < 1e-4, 1.0, (hi - lo) / 2)
        return center, scale, True
    if mode == "limits":
        # Diffusion Policy's LinearNormalizer "limits" fit, written as its scale/offset and
        # converted: y = x*scale + offset  <=>  y = (x - center)/s with s = 1/scale.
        lo, hi = x.min(axis=0), x.max(axis=0)
        rng = hi - lo
        ignore = rng < 1e-4
        rng = np.where(ignore, 2.0, rng)
        dp_scale = 2.0 / rng
        dp_offset = np.where(ignore, 0.0 - lo, -1.0 - dp_scale * lo)
        return -dp_offset / dp_scale, 1.0 / dp_scale, False
    if mode == "quantile":
        q01, q99 = np.percentile(x, 1, axis=0), np.percentile(x, 99, axis=0)
        r = q99 - q01 + 1e-6
        return q01 + r / 2, r / 2, False
    if mode == "lerobot_mean_std":
        return x.mean(axis=0), x.std(axis=0) + 1e-8, False
    if mode == "lerobot_min_max":
        r = x.max(axis=0) - x.min(axis=0) + 1e-8
        return x.min(axis=0) + r / 2, r / 2, False
    raise ValueError(mode)


def normalize(x, params):
    center, scale, clip = params
    y = (np.asarray(x, dtype=np.float64) - center) / scale
    return np.clip(y, -1, 1) if clip else y


def expected_starts(length, chunk, obs_history, padding, stride, lead=0, max_pad_after=None):
    """Current steps t of the samples of one episode (see the book's windows chapter)."""
    if padding == "truncate":
        first, end = max(obs_history - 1, lead), min(length - chunk + lead + 1, length)
    else:
        first, end = 0, length
        if max_pad_after is not None:
            end = min(end, length + max_pad_after + lead - chunk + 1)
    return list(range(first, end, stride)) if end > first else []


def action_window(actions, t, chunk, padding, params, lead=0):
    """Normalized action chunk and pad mask for the sample at step t of one episode."""
    length = len(actions)
    rows = np.arange(t - lead, t - lead + chunk)
    is_pad = (rows < 0) | (rows >= length)
    raw = actions[np.clip(rows, 0, length - 1)].astype(np.float64)  # edge repetition
    out = normalize(raw, params)
    if padding == "zero":
        out[is_pad] = normalize(np.zeros((1, actions.shape[1])), params)[0]
    elif padding == "mask":
        out[is_pad] = 0.0
    return out, is_pad


def obs_window(values, t, obs_history):
    rows = np.maximum(np.arange(t - obs_history + 1, t + 1), 0)
    return values[rows]
