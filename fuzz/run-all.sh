#!/bin/sh
# Runs every fuzz target in turn for $SECS seconds (default 600), one job,
# niced; logs in fuzz/logs/<target>.log. Usage: fuzz/run-all.sh [targets...]
cd "$(dirname "$0")" || exit 1
SECS=${SECS:-600}
TARGETS=${*:-"mat_reader csv_reader model_json model_toml model_extends model_graybox expression prior_toml experiment_toml"}
mkdir -p logs
for t in $TARGETS; do
  mkdir -p "work/$t"
  echo "== $t $(date -u +%FT%TZ)" > "logs/$t.log"
  RUSTC_BOOTSTRAP=1 nice -n 10 cargo fuzz run "$t" "work/$t" "corpus/$t" -- \
    -max_total_time="$SECS" -jobs=1 -workers=1 -print_final_stats=1 >> "logs/$t.log" 2>&1
  echo "== exit $? $(date -u +%FT%TZ)" >> "logs/$t.log"
  cat fuzz-0.log >> "logs/$t.log" 2>/dev/null; rm -f fuzz-0.log
done
