#!/usr/bin/env bash
# Per-image verdicts (id, pass, category, count, area, phase label) of fixed sets, for a change
# meant to keep every verdict (a refactoring): run before and after and diff the two lists; an
# empty diff means the same verdicts. Sets: eyrc seed 123 and eyrc-hard seed 5 (COUNT scenes
# each, default 40); pipelines: the built-in reference, and a competition style run as a --cmd
# (warm, and --no-warm), with eyrc's default phase check.
#   tools/verdicts.sh > before.txt   # ... change ...   tools/verdicts.sh | diff before.txt -
set -euo pipefail
cd "$(dirname "$0")/.."
count=${COUNT:-40}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ab=.venv/bin/arenabench
style="{python} $PWD/tests/pipelines/style_canny.py --image {image}"
for set in "eyrc 123" "eyrc-hard 5"; do
  read -r preset seed <<<"$set"
  $ab generate --preset "$preset" --count "$count" --seed "$seed" --workers 2 \
    --out "$tmp/$preset" --no-progress >/dev/null
  for run in reference cmd-warm cmd-cold; do
    case $run in
      reference) args=(--pipeline reference) ;;
      cmd-warm) args=(--cmd "$style") ;;
      cmd-cold) args=(--cmd "$style" --no-warm) ;;
    esac
    $ab eval "$tmp/$preset" "${args[@]}" --out "$tmp/out-$preset-$run" --formats json \
      --workers 2 --no-progress >/dev/null || true
    .venv/bin/python - "$tmp/out-$preset-$run/report.json" "$preset/$run" <<'EOF'
import json
import sys

doc = json.load(open(sys.argv[1]))
for r in doc["images"]:
    phase = (r.get("phase") or {}).get("class")
    print(sys.argv[2], r["id"], r["pass"], r["category"], r["pred"]["count"],
          r["pred"]["area"], phase)
EOF
  done
done
