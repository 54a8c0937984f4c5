#!/usr/bin/env bash
# Regenerate the benchmark report, benches/README.md, on the current code: every table and plot it
# shows is rerun here, and nothing else goes into it.
#
# Usage: scripts/report.sh [PART ...]      (from anywhere; honours CARGO_TARGET_DIR)
#
# PARTs: cloth-40 beam-4 cloth-160 sweep scale hard-cases sph kernels refill (default: all of them, in
# that order; about an hour on a quiet 2-core machine, most of it cloth-160's Newton rows, the
# sweep's reference states and the criterion kernels). A part writes its raw records (text output,
# JSON, CSV, its command and the machine's state) to benches/results/current/PART.*, and its plot
# to benches/PART*.png; then the report is assembled from benches/README.template.md and every
# part's records. Rerunning some parts only leaves the others' records, each stamped with its own
# commit, date and load, so the report never shows a figure without the run that made it.
#
# Every file is written to a temporary name and renamed onto its place when complete: an
# interrupted run leaves the previous records, plots and report whole.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
results=benches/results/current
mkdir -p "$results" "$root/out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

all_parts=(cloth-40 beam-4 cloth-160 sweep scale hard-cases sph kernels refill)
if [ $# -eq 0 ]; then
    parts=("${all_parts[@]}")
else
    parts=("$@")
    for p in "${parts[@]}"; do
        case " ${all_parts[*]} " in
        *" $p "*) ;;
        *) echo "error: unknown part '$p' (parts: ${all_parts[*]})" >&2; exit 2 ;;
        esac
    done
fi

cargo build --release --quiet --bin hooke
bin="${CARGO_TARGET_DIR:-$root/target}/release/hooke"

# place SRC DEST: DEST's replacement, renamed onto it when complete.
place() {
    local tmp
    tmp="$(dirname "$2")/.$(basename "$2").tmp"
    cp "$1" "$tmp"
    mv -f "$tmp" "$2"
}

commit() {
    local c
    c=$(git rev-parse --short HEAD)
    if ! git diff --quiet HEAD -- crates src Cargo.toml Cargo.lock; then c="$c + uncommitted changes"; fi
    echo "$c"
}

load() { cut -d' ' -f1 /proc/loadavg; }

# run PART CMD...: run CMD (output to $work/PART.txt), then record how it ran in PART.meta.
run() {
    local part=$1
    shift
    local start load0
    start=$(date -u '+%Y-%m-%d %H:%M')
    load0=$(load)
    echo "[$(date -u +%H:%M:%S)] $part: $*" >&2
    "$@" > "$work/$part.txt"
    {
        echo "commit: $(commit)"
        echo "date: $start-$(date -u +%H:%M) UTC"
        echo "load: $load0 -> $(load) (load average over 1 min, at start and end)"
        # The command as a reader reruns it: `hooke` for the binary, file names without the
        # temporary directory (records land in $results, plots beside the report).
        local shown=${*//$bin/hooke}
        echo "command: ${shown//$work\//}"
    } > "$work/$part.meta"
    for f in "$work/$part".*; do place "$f" "$results/$(basename "$f")"; done
}

# bench_scene SCENE: the speed-vs-error step of SCENE with the default solver list.
bench_scene() {
    local s=$1
    run "$s" "$bin" bench "$s" --quiet \
        --json "$work/$s.json" --csv "$work/$s.csv" --plot "$work/$s-pareto.png"
    place "$work/$s-pareto.png" "benches/$s-pareto.png"
}

for part in "${parts[@]}"; do
    case $part in
    cloth-40 | beam-4 | cloth-160) bench_scene "$part" ;;
    sweep)
        # From the speed-vs-error state: its 10 exact steps are what bounds the size here.
        run sweep "$bin" bench --sweep N=10,20,40,80,160 --from-state --quiet \
            --solver pd:10 --solver newton-tol:1e-8 --solver newton-cg-amg-tol:1e-8 \
            --json "$work/sweep.json" --csv "$work/sweep.csv" --plot "$work/sweep.png"
        place "$results/sweep.png" benches/sweep.png
        rm -f "$results/sweep.png"
        ;;
    scale)
        # The first step from rest, up to 409,600 vertices: how PD's step grows with size.
        run scale "$bin" bench --sweep N=40,80,160,320,640 --quiet --solver pd:10 \
            --json "$work/scale.json" --csv "$work/scale.csv" --plot "$work/scale.png"
        place "$results/scale.png" benches/scale.png
        rm -f "$results/scale.png"
        ;;
    hard-cases) run hard-cases "$bin" bench --hard-cases --quiet ;;
    sph) run sph "$bin" bench --sph 1e3,1e4,1e5,dam-break-2d --quiet ;;
    kernels) run kernels cargo bench --quiet --bench solver_kernels ;;
    refill) run refill cargo bench --quiet --bench hessian_refill ;;
    esac
done

# Assemble the report: each "@@PART@@" line of the template becomes the part's run (commit, date,
# load, command) and its output, verbatim; each line of the template is kept as it is otherwise.
report="$work/README.md"
while IFS= read -r line; do
    if [[ $line =~ ^@@([a-z0-9-]+)@@$ ]]; then
        part=${BASH_REMATCH[1]}
        if [ ! -f "$results/$part.txt" ]; then
            echo "error: the template shows part '$part', which has no records yet: run scripts/report.sh $part" >&2
            exit 1
        fi
        echo '```text'
        cat "$results/$part.meta"
        echo
        cat "$results/$part.txt"
        echo '```'
    else
        printf '%s\n' "$line"
    fi
done < benches/README.template.md > "$report"
place "$report" benches/README.md
echo "wrote benches/README.md" >&2
