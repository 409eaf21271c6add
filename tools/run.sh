#!/usr/bin/env bash
# The README's main command: set up what is missing, then run the main job.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$ROOT/tools/bootstrap.sh"
cd "$ROOT"
"$ROOT/.venv/bin/delta6" design designs/delta6.toml
echo
exec "$ROOT/.venv/bin/delta6" design designs/*.toml
