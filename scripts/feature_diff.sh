#!/usr/bin/env bash
# The features cargo resolves for the crates springfit and the Python package (python/) share,
# where they differ: empty output means `pip install ./python` reuses every dependency that
# `cargo build --release` compiled (issue 42, item 6). Exit 1 when any differs.
set -euo pipefail
cd "$(dirname "$0")/.."
tree() { cargo tree --locked -p "$1" -e normal,build --prefix none -f '{p} [{f}]' | sed 's/ (\*)$//' | sort -u; }
differ=$(diff <(tree springfit) <(tree springfit-python) || true)
printf '%s\n' "$differ" | { grep '^[<>]' || true; } | awk '
  { name = $2 " " $3; side = $1; sub(/^[<>] /, ""); seen[name] = seen[name] side; line[name, side] = $0 }
  END { bad = 0; for (n in seen) if (seen[n] == "<>" || seen[n] == "><") { print "springfit:        " line[n, "<"]; print "springfit-python: " line[n, ">"]; bad = 1 } exit bad }'
