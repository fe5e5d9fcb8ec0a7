#!/usr/bin/env bash
# Times chunkc on the full Push-T replay buffer (not vendored: pass its path).
#
#   bench/pusht_full.sh /path/to/pusht_cchi_v7_replay.zarr [workdir]
#
# Prints wall time and peak RSS for: the demo's two profiles with images at 1 and 2 threads; the
# first half of the episodes vs all of them (peak RSS must not grow with the dataset); and four
# profiles at two rates from one spec vs the same four profiles built one spec at a time.
set -euo pipefail
src=$(realpath "$1")
work=${2:-$(mktemp -d)}
bin=$(realpath "$(dirname "$0")/../target/release/chunkc")
mkdir -p "$work"

spec() { # name source profiles...
  local name=$1 source=$2; shift 2
  {
    printf 'version = 1\n[source]\nformat = "diffusion_policy_zarr"\npath = "%s"\nfps = 10\n' "$source"
    printf '[source.channels]\naction = "action"\n"observation.state" = "state"\n"observation.image" = "img"\n'
    printf '[output]\ndir = "out-%s"\n' "$name"
    for p in "$@"; do printf '%b\n' "$p"; done
  } > "$work/$name.toml"
}

ACT='[profiles.act]\npreset = "act"\nfps = 10\nchunk = 20'
DP='[profiles.dp]\npreset = "diffusion_policy"'
DP5='[profiles.dp5]\npreset = "diffusion_policy"\nfps = 5\nchunk = 8'
PI='[profiles.openpi]\npreset = "openpi"\nfps = 5\nchunk = 10'

measure() { # label threads spec
  rm -rf "$work"/out-* "$work/chunkc.lock"
  local t
  t=$( { RAYON_NUM_THREADS=$2 /usr/bin/time -f "%e %M" "$bin" build -q "$3" >/dev/null; } 2>&1 | tail -1)
  printf '%-40s threads=%s  wall %6ss  peak RSS %6.0f MiB\n' "$1" "$2" "${t% *}" "$(echo "${t#* } / 1024" | bc -l)"
}

spec two "$src" "$ACT" "$DP"
measure "2 profiles (act, dp), images" 1 "$work/two.toml"
measure "2 profiles (act, dp), images" 2 "$work/two.toml"

half="$work/half.zarr"
if [ ! -d "$half" ]; then
  N_EPISODES=103 "$(dirname "$0")/../.venv/bin/python" "$(dirname "$0")/../tests/data/make_pusht_subset.py" "$src" "$half" >/dev/null
fi
spec half "$half" "$ACT" "$DP"
measure "103 episodes (N)" 2 "$work/half.toml"
measure "206 episodes (2N)" 2 "$work/two.toml"

spec four "$src" "$ACT" "$DP" "$DP5" "$PI"
measure "4 profiles, 2 rates, one spec" 2 "$work/four.toml"
start=$(date +%s.%N)
for p in "$ACT" "$DP" "$DP5" "$PI"; do
  spec one "$src" "$p"
  rm -rf "$work"/out-one "$work/chunkc.lock"
  RAYON_NUM_THREADS=2 "$bin" build -q "$work/one.toml"
done
printf '%-40s threads=2  wall %6.2fs\n' "same 4 profiles, one spec at a time" "$(echo "$(date +%s.%N) - $start" | bc -l)"
