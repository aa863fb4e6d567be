#!/usr/bin/env bash
# Roll a mission out to real drones and fly it (paper V-E, VI-E to VI-G):
#
#   scripts/rollout.sh MISSION.go FLEET.toml [eamos rollout options...]
#
# 1. `eamos rollout`: compile here, check every drone over SSH (reachable, same
#    eamos version, disk), copy only what changed, start eamos-node on each drone;
# 2. `eamos start`:   the ground station: wait until all are ready, send the start
#    trigger, show progress, write summary.json (paper Table 7 durations included);
# 3. `eamos logs fetch`: collect every drone's logs into the run folder;
# 4. `eamos report`:  write RUN_DIR/report.html (timeline, trajectories, Table 7).
#
# The logic, the checks and the error messages are in eamos/ops/ (Python);
# this script only chains the commands.  The eamos it runs: EAMOS if set, else
# the one the README's install made next to this script (.venv/bin/eamos in the
# checkout), else eamos on PATH.  RUN_DIR names the run folder (default
# runs/<mission>-<date-time>).  Exit code: the first failing step's (0 when the
# mission finished; 2 for bad input, an eamos that cannot be found included).
set -euo pipefail

usage() { sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; }
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then usage; exit 0; fi
if [[ $# -lt 2 ]]; then usage >&2; exit 2; fi
mission=$1
fleet=$2
shift 2
checkout=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [[ -n "${EAMOS:-}" ]]; then
  read -r -a eamos <<<"$EAMOS"  # may be a command with arguments ("python -m eamos.cli")
elif [[ -x "$checkout/.venv/bin/eamos" ]]; then
  eamos=("$checkout/.venv/bin/eamos")
elif command -v eamos >/dev/null 2>&1; then
  eamos=(eamos)
else
  cat >&2 <<EOF
rollout.sh: eamos not found: neither $checkout/.venv/bin/eamos nor eamos on PATH.
Install it as the README says, in the checkout:
  cd $checkout && python3 -m venv .venv && .venv/bin/pip install -q -e .
or put an installed eamos on PATH (export PATH="/path/to/venv/bin:\$PATH"),
or name it: EAMOS=/path/to/venv/bin/eamos $0 ...
EOF
  exit 2
fi
run_dir=${RUN_DIR:-runs/$(basename "$mission" .go)-$(date +%Y%m%d-%H%M%S)}

"${eamos[@]}" rollout "$mission" "$fleet" --run-dir "$run_dir" "$@"
status=0
"${eamos[@]}" start "$run_dir" || status=$?
# The logs are wanted most when something went wrong: fetch them either way.
"${eamos[@]}" logs fetch "$run_dir" || true
"${eamos[@]}" report "$run_dir" || true
exit "$status"
