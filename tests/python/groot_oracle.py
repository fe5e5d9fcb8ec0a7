"""An oracle of what NVIDIA Isaac-GR00T N1.7 reads from a LeRobot v2.1 dataset, written from its
published semantics (GR00T is not on the package index, so its code cannot run here):

- `gr00t/data/dataset/lerobot_episode_loader.py` (`LeRobotEpisodeLoader`): `meta/info.json`
  (`data_path`, `video_path`, `chunks_size`, `features`), `meta/episodes.jsonl`,
  `meta/tasks.jsonl`, `meta/modality.json` (a state/action part is `column[start:end]` of its
  `original_key`, default `observation.state` / `action`; a video key's `original_key` must be
  a feature of info.json; an annotation maps `task_index` through tasks.jsonl), and
  `meta/stats.json`, which must exist; every episode's video frames must number its rows;
- `gr00t/data/stats.py`: `calculate_dataset_statistics` (every feature of info.json whose dtype
  contains "float", stacked as float32 over every parquet file: mean, std, min, max, and
  `np.quantile` at 0.01 and 0.99, numpy's default linear definition), `check_stats_validity`
  (the shipped file is kept when every such feature has the six keys), and the relative action
  statistics (per relative key: every chunk `action[t : t + H]` of a part minus the state part
  of the same name at `t`, for `t` in `0 .. length - H`, computed in float64 and kept as
  float32; the six statistics over the chunks, shape (H, D));
- the sampling of N1.6/N1.7 (`sharded_single_step_dataset.py`): state and video at offset 0,
  action offsets `range(H)`, and only start steps whose chunk fits (`length - H + 1`).
"""

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

STATS = ("mean", "std", "min", "max", "q01", "q99")


def six(data):
    """GR00T's six statistics over axis 0 of `data`, as numpy computes them on it."""
    return {
        "mean": np.mean(data, axis=0), "std": np.std(data, axis=0),
        "min": np.min(data, axis=0), "max": np.max(data, axis=0),
        "q01": np.quantile(data, 0.01, axis=0), "q99": np.quantile(data, 0.99, axis=0),
    }


class GrootDataset:
    """A dataset as GR00T's loader sees it; every check the loader makes is an assertion here."""

    def __init__(self, root):
        self.root = Path(root)
        meta = self.root / "meta"
        self.info = json.loads((meta / "info.json").read_text())
        self.episodes = [json.loads(x) for x in (meta / "episodes.jsonl").read_text().splitlines()]
        tasks = [json.loads(x) for x in (meta / "tasks.jsonl").read_text().splitlines()]
        self.tasks = {t["task_index"]: t["task"] for t in tasks}
        self.modality = json.loads((meta / "modality.json").read_text())
        assert (meta / "stats.json").exists(), "GR00T asserts meta/stats.json exists"
        self.stats = json.loads((meta / "stats.json").read_text())
        rel = meta / "relative_stats.json"
        self.relative_stats = json.loads(rel.read_text()) if rel.exists() else None
        for group in ("state", "action", "video"):
            assert group in self.modality, f"modality.json has no `{group}`"
        for key, part in self.modality["video"].items():
            original = part.get("original_key", f"observation.images.{key}")
            assert original in self.info["features"], f"{original} not in info.json"

    def table(self, e):
        """Episode `e`'s parquet rows, as pandas reads them."""
        chunk = e // self.info["chunks_size"]
        path = self.root / self.info["data_path"].format(episode_chunk=chunk, episode_index=e)
        return pq.read_table(path).to_pandas()

    def column(self, df, name):
        return np.stack([np.asarray(x, dtype=np.float32).reshape(-1) for x in df[name]])

    def part(self, df, group, key):
        """A state or action part of an episode: (rows, end - start), GR00T's slice."""
        p = self.modality[group][key]
        original = p.get("original_key", {"state": "observation.state", "action": "action"}[group])
        # GR00T slices a row only where pandas gives it as an array (else it takes the scalar).
        assert isinstance(df[original].iloc[0], np.ndarray), f"{original} is not a vector column"
        return self.column(df, original)[:, p["start"]:p["end"]]

    def language(self, df):
        """Each row's task description (`annotation.human.task_description`)."""
        original = self.modality["annotation"]["human.task_description"]["original_key"]
        return [self.tasks[int(i)] for i in df[original]]

    def video_path(self, e, key):
        original = self.modality["video"][key].get("original_key", f"observation.images.{key}")
        chunk = e // self.info["chunks_size"]
        return self.root / self.info["video_path"].format(
            episode_chunk=chunk, video_key=original, episode_index=e)

    def samples(self, horizon):
        """N1.7's sample start steps per episode: those whose action chunk fits."""
        return [(i, t) for i, ep in enumerate(self.episodes)
                for t in range(ep["length"] - horizon + 1)]

    def float_features(self):
        return [k for k, f in self.info["features"].items() if "float" in f["dtype"]]

    def keeps_shipped_stats(self):
        """`check_stats_validity`: every float feature with the six statistics."""
        return all(k in self.stats and all(s in self.stats[k] for s in STATS)
                   for k in self.float_features())

    def computed_stats(self, dtype=np.float32):
        """`calculate_dataset_statistics` (in `dtype`: float32 is GR00T's own arithmetic,
        float64 the exact numbers of the same float32 values)."""
        frames = [self.table(e["episode_index"]) for e in self.episodes]
        out = {}
        for k in self.float_features():
            data = np.vstack([self.column(df, k) for df in frames]).astype(dtype)
            out[k] = six(data)
        return out

    def computed_relative_stats(self, keys, horizon, dtype=np.float32):
        """The relative action statistics of `keys` (state part of the same name), over the
        float32 chunks (in `dtype`, as `computed_stats`)."""
        out = {}
        for key in sorted(keys):
            chunks = []
            for e in self.episodes:
                df = self.table(e["episode_index"])
                state = self.part(df, "state", key).astype(np.float64)
                action = self.part(df, "action", key).astype(np.float64)
                for t in range(len(df) - horizon + 1):
                    chunks.append((action[t:t + horizon] - state[t]).astype(np.float32))
            out[key] = six(np.stack(chunks).astype(dtype))
        return out


def registered_config(path):
    """Runs a `groot_config.py` against stand-ins of the GR00T modules it imports (their names
    as Isaac-GR00T N1.7 has them) and returns what it registers: (embodiment tag name, config
    with each ModalityConfig as a dict, action configs as (rep, type, format) names)."""
    import sys
    import types

    registered = []

    class Names:
        def __getattr__(self, name):
            return name

    def modality_config(**kwargs):
        return kwargs

    def action_config(rep, type, format):
        return (rep, type, format)

    stubs = {
        "gr00t": types.ModuleType("gr00t"),
        "gr00t.configs": types.ModuleType("gr00t.configs"),
        "gr00t.configs.data": types.ModuleType("gr00t.configs.data"),
        "gr00t.configs.data.embodiment_configs": types.ModuleType("e"),
        "gr00t.data": types.ModuleType("gr00t.data"),
        "gr00t.data.embodiment_tags": types.ModuleType("t"),
        "gr00t.data.types": types.ModuleType("y"),
    }
    stubs["gr00t.configs.data.embodiment_configs"].register_modality_config = (
        lambda config, embodiment_tag: registered.append((embodiment_tag, config)))
    stubs["gr00t.data.embodiment_tags"].EmbodimentTag = Names()
    y = stubs["gr00t.data.types"]
    y.ActionConfig, y.ModalityConfig = action_config, modality_config
    y.ActionFormat = y.ActionRepresentation = y.ActionType = Names()
    saved = {k: sys.modules.get(k) for k in stubs}
    sys.modules.update(stubs)
    try:
        exec(compile(Path(path).read_text(), str(path), "exec"), {"__name__": "groot_config"})
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v
    assert len(registered) == 1, registered
    return registered[0]


def check_config(path, g, horizon, relative=()):
    """The registered config names exactly the dataset's modality keys, with N1.7's offsets."""
    tag, config = registered_config(path)
    assert tag == "NEW_EMBODIMENT"
    assert config["video"] == {"delta_indices": [0], "modality_keys": list(g.modality["video"])}
    assert config["state"] == {"delta_indices": [0], "modality_keys": list(g.modality["state"])}
    action = config["action"]
    assert action["delta_indices"] == list(range(horizon))
    assert action["modality_keys"] == list(g.modality["action"])
    reps = ["RELATIVE" if k in relative else "ABSOLUTE" for k in action["modality_keys"]]
    assert action["action_configs"] == [(r, "NON_EEF", "DEFAULT") for r in reps]
    for key in g.modality["annotation"]:
        assert config["language"] == {"delta_indices": [0], "modality_keys": [f"annotation.{key}"]}
