"""Diffusion Policy normalizer for the chunkc profile `robomimic` (generated; do not edit).

    from dp_normalizer import load_state_dict
    policy.load_state_dict(load_state_dict(), strict=False)   # or normalizer.load_state_dict(
                                                               #   load_state_dict(prefix=""))

`dp_normalizer.json` holds, per key, LinearNormalizer's `scale`, `offset` (forward
`x * scale + offset`) and `input_stats` {min, max, mean, std}, computed by chunkc on the training
split.
"""

import json
import os


def load_params(path=None):
    path = path or os.path.join(os.path.dirname(os.path.abspath(__file__)), "dp_normalizer.json")
    with open(path) as f:
        return json.load(f)


def load_state_dict(path=None, prefix="normalizer."):
    """The LinearNormalizer state dict: `<prefix>params_dict.<key>.scale`, `.offset`,
    `.input_stats.{min,max,mean,std}` as float32 tensors."""
    import torch

    state = {}
    for key, p in load_params(path).items():
        base = f"{prefix}params_dict.{key}."
        state[base + "scale"] = torch.tensor(p["scale"], dtype=torch.float32)
        state[base + "offset"] = torch.tensor(p["offset"], dtype=torch.float32)
        for stat, value in p["input_stats"].items():
            state[base + "input_stats." + stat] = torch.tensor(value, dtype=torch.float32)
    return state


def normalize(key, x, path=None):
    """x * scale + offset, with numpy."""
    import numpy as np

    p = load_params(path)[key]
    return np.asarray(x) * np.asarray(p["scale"]) + np.asarray(p["offset"])
