#!/usr/bin/env bash
# The two commands of the README:
#   ./run.sh demo   set everything up, then run the main job (evedge demo)
#   ./run.sh test   set everything up, then run the test suite
set -euo pipefail
cd "$(dirname "$0")"
case "${1:-}" in
  demo) shift; bash scripts/setup.sh; exec .venv/bin/evedge demo --overwrite "$@" ;;
  test) shift; bash scripts/setup.sh; exec .venv/bin/python -m pytest "$@" ;;
  setup) bash scripts/setup.sh ;;
  *) echo "usage: ./run.sh demo|test|setup [args passed on]" >&2; exit 2 ;;
esac
