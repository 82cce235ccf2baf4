#!/usr/bin/env bash
# Hashes of every generated file (images, GT, coco.json) of every preset, seed 0, 50 scenes:
# run before and after a refactoring and diff the two lists; an empty diff means the outputs
# are byte-identical (docs/architecture.md, "Golden outputs").
#   tools/output-hashes.sh > before.sha256   # ... change ...   tools/output-hashes.sh | diff before.sha256 -
set -euo pipefail
cd "$(dirname "$0")/.."
count=${COUNT:-50}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
presets=$(.venv/bin/python -c "from arenabench.generator.parameters.presets import PRESETS; print(' '.join(PRESETS))")
for p in $presets; do
  .venv/bin/arenabench generate --preset "$p" --count "$count" --seed 0 --workers 2 \
    --out "$tmp/$p" --no-progress >/dev/null
done
cd "$tmp" && find . -type f \( -path '*/images/*' -o -path '*/gt/*' -o -name coco.json \) -print0 \
  | sort -z | xargs -0 sha256sum
