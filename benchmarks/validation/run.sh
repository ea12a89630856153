#!/bin/sh
# Run sensitivity campaigns into OUT, keeping their runs in the repository as they go.
#
#   benchmarks/validation/run.sh OUT CAMPAIGN [PATTERN ...]
#
# CAMPAIGN is a file of benchmarks/validation/configs/ without .toml (sensitivity,
# time-600-seed-1, ...) or the path of a campaign file (benchmarks/validation/rcp.toml,
# examples/grading.toml); PATTERNs select its mixtures (granpack campaign --mixture), all if
# none. WORKERS (default 2) sets the number of runs at once.
# The kept runs of benchmarks/validation/runs/CAMPAIGN are restored into OUT/CAMPAIGN first (the
# finished ones are skipped, the checkpointed ones resumed); the runs are saved back every 15
# minutes and at the end, so that a stop loses at most the last checkpoint interval. Their final.gsd
# is saved too, for analyses made afterwards (contact types, layers), but .gitignore keeps it out of
# commits: commit what is derived from it (benchmarks/final_states.py says where final states live).
set -eu
out=$1; campaign=$2; shift 2
here=$(cd "$(dirname "$0")" && pwd)
case $campaign in
  *.toml) spec=$(cd "$(dirname "$campaign")" && pwd)/$(basename "$campaign"); campaign=$(basename "$campaign" .toml) ;;
  *) spec="$here/configs/$campaign.toml" ;;
esac
kept="$here/runs/$campaign"
dir="$out/$campaign"
mkdir -p "$dir" "$kept"
save() { python "$here/../study_runs.py" save "$dir" --kept "$kept" --final; }
python "$here/../study_runs.py" restore "$dir" --kept "$kept"
set --  $(for p in "$@"; do printf -- '--mixture %s ' "$p"; done)
( while sleep 900; do save; done ) &
saver=$!
trap 'kill $saver 2>/dev/null; save' EXIT
granpack campaign "$spec" --out "$dir" --workers "${WORKERS:-2}" "$@"
