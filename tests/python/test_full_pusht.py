"""The full 206-episode Push-T replay buffer, images included (opt-in: it is not vendored).

    CHUNKC_FULL_PUSHT=/path/to/pusht_cchi_v7_replay.zarr scripts/test.sh
"""

import json
import os
import resource
from pathlib import Path

import numpy as np
import pytest

from conftest import RawSource, import_loader, run_chunkc, write_spec
from reference import action_window, norm_params

FULL = os.environ.get("CHUNKC_FULL_PUSHT")
pytestmark = pytest.mark.skipif(not FULL, reason="set CHUNKC_FULL_PUSHT to the full Push-T zarr")

PROFILES = """
[profiles.dp]
preset = "diffusion_policy"

[profiles.act]
preset = "act"
fps = 10
chunk = 20
"""


def test_full_pusht_builds_and_matches_numpy(tmp_path):
    spec = write_spec(tmp_path, PROFILES, source=Path(FULL))
    run_chunkc("build", "-q", spec)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"peak RSS of chunkc build: {children.ru_maxrss / 1024:.0f} MiB")
    raw = RawSource(Path(FULL))
    meta = json.loads((tmp_path / "out" / "dp" / "meta.json").read_text())
    assert len(meta["episodes"]) == len(raw.ends) == 206
    assert meta["episode_ends"][-1] == raw.ends[-1] == 25650
    stats = json.loads((tmp_path / "out" / "dp" / "stats.json").read_text())
    train = np.concatenate([raw.episode("action", e) for e in meta["split"]["train"]]).astype(np.float64)
    np.testing.assert_allclose(stats["action"]["p999"], np.percentile(train, 99.9, axis=0), rtol=1e-6)

    loader = import_loader(tmp_path / "out" / "dp")
    ds = loader.ChunkedDataset(str(tmp_path / "out" / "dp"))
    params = norm_params(meta["normalization"]["action"]["mode"], train)
    lead = meta["action_lead"]
    for i in range(0, len(ds), 997):
        s = ds[i]
        e, t = s["episode_index"], s["frame_index"]
        want, pad = action_window(raw.episode("action", e), t, 16, "edge", params, lead)
        np.testing.assert_allclose(s["action"], want, rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(s["action_is_pad"], pad)
        img = raw.episode("img", e)[max(t - 1, 0) : t + 1]
        np.testing.assert_array_equal(s["observation.image"][-1], img[-1].astype(np.uint8))
