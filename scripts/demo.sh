#!/usr/bin/env bash
# Builds the shipped Push-T subset (specs/pusht.toml, 20 episodes in tests/data) and reads a sample
# back through each generated loader. Works from any directory.
set -euo pipefail
exec 2>&1 # one stream, so that piped output stays in order
cd "$(dirname "${BASH_SOURCE[0]}")/.."
. scripts/setup.sh

chunkc=target/release/chunkc
spec=specs/pusht.toml
if [ -t 1 ]; then bold=$'\033[1m' plain=$'\033[0m'; else bold='' plain=''; fi
step() { printf '\n%s== %s%s\n' "$bold" "$*" "$plain"; }

step "$chunkc plan $spec"
"$chunkc" plan "$spec"

step "$chunkc build $spec"
"$chunkc" build "$spec"

step "$chunkc build --locked $spec   (a second build has nothing to do)"
"$chunkc" build --locked "$spec"

for loader in out/pusht/*/loader.py; do
    step ".venv/bin/python $loader"
    .venv/bin/python "$loader"
done

step "reading a sample in Python (out/pusht/dp)"
.venv/bin/python - <<'PY'
import sys
sys.path.insert(0, "out/pusht/dp")
from loader import ChunkedDataset, make_dataloader

ds = ChunkedDataset("out/pusht/dp", split="train")
s = ds[0]
print(f"episode {s['episode_index']}, frame {s['frame_index']}: "
      f"action {s['action'].shape} in [{s['action'].min():.3f}, {s['action'].max():.3f}] (normalized)")
print("first action, raw units:", ds.denormalize("action", s["action"][0]).round(2))
try:
    import torch  # noqa: F401  (the model tier of tests/python/requirements.txt)
except ImportError:
    print("torch is not installed (setup installed the core Python tier): no DataLoader batch")
else:
    batch = next(iter(make_dataloader("out/pusht/dp", "train", batch_size=8)))
    print({k: tuple(v.shape) for k, v in batch.items()})
PY

printf '\ndemo: done; outputs in out/pusht/, lock in specs/chunkc.lock\n'
