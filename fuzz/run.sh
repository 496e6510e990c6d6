#!/usr/bin/env bash
# Builds the fuzz targets and runs each for SECONDS (default 600) in turn, one process each,
# logging to fuzz/logs/<target>.log. Run from fuzz/: ./run.sh [SECONDS]
set -u
cd "$(dirname "$0")"
secs="${1:-600}"
mkdir -p logs
cargo +nightly fuzz build || exit 1
status=0
for target in scene_bytes scene_structured gltf_bytes path_resolution; do
  case "$target" in
    gltf_bytes) extra="-dict=gltf.dict -max_len=16384" ;;
    path_resolution) extra="-max_len=256" ;;
    *) extra="-dict=scene.dict -max_len=16384" ;;
  esac
  # Corpus: the committed seeds (seed_*) plus what the run adds; new crashes go to artifacts/.
  cargo +nightly fuzz run "$target" -- \
    -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
    $extra -print_final_stats=1 \
    > "logs/$target.log" 2>&1 || status=1
  tail -n 30 "logs/$target.log" | grep -E "stat::number_of_executed_units|Done|ERROR|SUMMARY" || true
done
exit $status
