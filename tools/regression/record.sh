#!/usr/bin/env bash
# Record the four results a "no numerical change" step must keep, into OUT:
#   bash tools/regression/record.sh OUT
# (the installed rbbench; run from the repository root, which asv benchmarks). Compare two
# recordings with: python -m tools.regression.compare BEFORE AFTER
set -euo pipefail
OUT=$(realpath -m "${1:?usage: record.sh OUT}")
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$OUT"
echo "== quick run $(date)"
rbbench run quick --out "$OUT/quick" --cache-dir "$OUT/cache" --quiet > "$OUT/quick.log" 2>&1
echo "== friction reduction $(date)"
rbbench reduce hertz_friction --set discretization.degree=1 -N 20 -R 10 -S 10 --n-train 15 \
  --n-valid 6 --k-max 20 --friction-dual wedge --hyper eim --cache-dir "$OUT/cache" \
  --out "$OUT/friction" > "$OUT/friction.log" 2>&1
echo "== shape optimisation $(date)"
rbbench optimize shape_coulomb --metric bfgs --max-iter 20 --out "$OUT/optimize" \
  > "$OUT/optimize.log" 2>&1
echo "== asv tracked values $(date)"
cd "$ROOT"
rm -rf "$OUT/asv_results" .asv/results
asv machine --yes > "$OUT/asv_machine.log" 2>&1
asv run --python=same --quick --bench 'track_' --show-stderr \
  --set-commit-hash "$(git rev-parse HEAD)" > "$OUT/asv.log" 2>&1
cp -r .asv/results "$OUT/asv_results"
echo "== done $(date)"
