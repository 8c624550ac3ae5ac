#!/usr/bin/env bash
# Crash safety of long jobs (CTest precompute_survives_kills; docs/reliability.md).
#
#   crash_test.sh PRT_PRECOMPUTE PRT_MAKE_SHAPE WORKDIR [KILLS]
#
# A job file of three precomputes (a generated sphere, three materials) is run once
# uninterrupted for reference bytes. Then KILLS times (default 20): start the job
# file, kill it at a random moment of its run (SIGKILL mostly, every 5th SIGTERM,
# every 7th SIGINT), and check that
#   - every output present is byte-identical to the uninterrupted one (a partial or
#     corrupt file where an output belongs is a "broken output"; goal 0);
#   - re-running the job file completes, every output equals the reference bytes
#     ("resumed correctly"), and no temporary file is left behind.
# The kill moments are drawn from a fixed seed, so a failure reproduces.
set -u
if [ $# -lt 3 ]; then
    echo "usage: $0 PRT_PRECOMPUTE PRT_MAKE_SHAPE WORKDIR [KILLS]" >&2
    exit 2
fi
PRECOMPUTE=$1 MAKE_SHAPE=$2 WORK=$3 KILLS=${4:-20}
rm -rf "$WORK"
mkdir -p "$WORK/ref" "$WORK/out"
"$MAKE_SHAPE" icosphere "$WORK/sphere.obj" --subdivisions 3 --radius 10 > /dev/null || exit 1

jobs_for() {  # jobs_for DIR: the job file writing into DIR
    cat <<JSON
{"defaults": {"mesh": "$WORK/sphere.obj", "size-mm": 20, "cubemap-size": 16, "samples": 3000},
 "jobs": [{"material": "Marble", "output": "$1/marble.prt"},
          {"material": "Skin1", "output": "$1/skin.prt"},
          {"material": "Ketchup", "output": "$1/ketchup.prt"}]}
JSON
}
jobs_for "$WORK/ref" > "$WORK/ref.json"
jobs_for "$WORK/out" > "$WORK/out.json"

start=$(date +%s%N)
"$PRECOMPUTE" --jobs "$WORK/ref.json" -j 2 -q > "$WORK/ref.log" 2>&1 || { echo "FAIL: reference run"; cat "$WORK/ref.log"; exit 1; }
duration_ms=$(( ($(date +%s%N) - start) / 1000000 ))
echo "uninterrupted run: ${duration_ms} ms"

RANDOM=12345
broken=0 resumed=0 killed=0
for ((k = 1; k <= KILLS; k++)); do
    rm -f "$WORK"/out/*
    # Half the kills in the first job (often before any output exists), half anywhere.
    if (( k % 2 )); then window=$(( duration_ms / 3 )); else window=$duration_ms; fi
    delay_ms=$(( (RANDOM * 32768 + RANDOM) % (window > 1 ? window : 1) ))
    signal=KILL
    (( k % 5 == 0 )) && signal=TERM
    (( k % 7 == 0 )) && signal=INT
    "$PRECOMPUTE" --jobs "$WORK/out.json" -j 2 -q > /dev/null 2>&1 &
    pid=$!
    sleep "$(printf '%d.%03d' $((delay_ms / 1000)) $((delay_ms % 1000)))"
    if kill -s "$signal" "$pid" 2> /dev/null; then killed=$((killed + 1)); fi
    wait "$pid" 2> /dev/null
    for f in marble skin ketchup; do
        if [ -e "$WORK/out/$f.prt" ] && ! cmp -s "$WORK/out/$f.prt" "$WORK/ref/$f.prt"; then
            echo "FAIL: kill $k ($signal after ${delay_ms} ms): $f.prt is present but not the complete output"
            broken=$((broken + 1))
        fi
    done
    # Resume: the job file again, to completion.
    if ! "$PRECOMPUTE" --jobs "$WORK/out.json" -j 2 -q > "$WORK/resume.log" 2>&1; then
        echo "FAIL: kill $k: the re-run failed:"; cat "$WORK/resume.log"; continue
    fi
    ok=1
    for f in marble skin ketchup; do
        cmp -s "$WORK/out/$f.prt" "$WORK/ref/$f.prt" || { echo "FAIL: kill $k: $f.prt differs after resuming"; ok=0; }
    done
    leftovers=$(find "$WORK/out" -name '*.tmp*' | wc -l)
    if [ "$leftovers" -ne 0 ]; then echo "FAIL: kill $k: $leftovers temporary files left after resuming"; ok=0; fi
    resumed=$((resumed + ok))
done
echo "kills: $KILLS attempted, $killed delivered while running; broken outputs: $broken; resumed correctly: $resumed/$KILLS"
[ "$broken" -eq 0 ] && [ "$resumed" -eq "$KILLS" ]
