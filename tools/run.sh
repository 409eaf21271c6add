#!/usr/bin/env bash
# The README's main command: set up what is missing, print the design report of the paper's
# Delta6 and the four shipped variants side by side, then start the virtual board (the real
# firmware on an emulated ATmega328P, its six encoders driven live by the digital twin) and
# stream its wrench. DELTA6_STREAM_SECONDS (default 20) sets how long;
# Ctrl-C ends the stream earlier. The board is stopped cleanly either way.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$ROOT/tools/bootstrap.sh"
cd "$ROOT"
D6="$ROOT/.venv/bin/delta6"

"$D6" design designs/delta6.toml
echo
"$D6" design designs/*.toml            # the four shipped variants side by side
echo

work=$(mktemp -d)
board_pid=
stop_board() {
  if [ -n "$board_pid" ] && kill -0 "$board_pid" 2>/dev/null; then
    kill -TERM "$board_pid" 2>/dev/null || true
    wait "$board_pid" || true
  fi
  board_pid=
}
trap 'stop_board; rm -rf "$work"' EXIT

"$D6" virtual --twin paper --twin-duration 120 > "$work/port" &
board_pid=$!
for _ in $(seq 1200); do
  [ -s "$work/port" ] && break
  if ! kill -0 "$board_pid" 2>/dev/null; then
    wait "$board_pid" || exit $?
    echo "run.sh: the virtual board ended before it opened its port" >&2
    exit 1
  fi
  sleep 0.1
done
port=$(head -n 1 "$work/port")
if [ -z "$port" ]; then
  echo "run.sh: the virtual board did not open its port within 120 s" >&2
  exit 1
fi
"$D6" stream --port "$port" --duration "${DELTA6_STREAM_SECONDS:-20}"
kill -TERM "$board_pid"
wait "$board_pid"
board_pid=
