#!/usr/bin/env bash
# Fuzz hooke's file readers and its scene-file parser with cargo-fuzz (libFuzzer).
#
# Usage: scripts/fuzz.sh [MINUTES] [TARGET...]
#   MINUTES  how long each target runs (default 5); the targets run one after another.
#   TARGET   any of: obj stl msh tetgen scene (default: all five).
#   Extra libFuzzer options go in FUZZ_ARGS, e.g. FUZZ_ARGS="-jobs=2 -workers=2".
#
# Needs cargo-fuzz (`cargo install cargo-fuzz`; not a project dependency). cargo-fuzz passes
# nightly-only flags (sanitizer coverage, -Zbuild-std is not used); on a stable toolchain this
# script sets RUSTC_BOOTSTRAP=1 so that stable rustc accepts them. Builds go to fuzz/target.
#
# Each target starts from a seed corpus in fuzz/corpus/TARGET (kept out of git): the files under
# data/meshes of its format and data/scenes for the scene parser, plus whatever earlier runs found.
# A crash, a timeout (-timeout, 10 s per input) or an input over -rss_limit_mb stops the target and
# leaves the input in fuzz/artifacts/TARGET/; the script goes on with the next target and exits
# non-zero at the end if any target failed. Reproduce one with
#   RUSTC_BOOTSTRAP=1 cargo fuzz run TARGET fuzz/artifacts/TARGET/crash-…
# and turn it into a regression test (tests/mesh_io.rs for the readers, tests/scenes.rs for the
# parser) before fixing it. Not run in CI: CI keeps the property tests on random and mutated bytes.
set -u

minutes=${1:-5}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(obj stl msh tetgen scene)
fi
case $minutes in
    '' | *[!0-9]*) echo "MINUTES must be a whole number, not '$minutes'" >&2; exit 2 ;;
esac

root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root/fuzz" || exit 2
export RUSTC_BOOTSTRAP=1

seed() {
    local target=$1 dir=corpus/$1
    mkdir -p "$dir"
    case $target in
        obj) cp -n "$root"/data/meshes/*.obj "$dir"/ ;;
        stl) find "$root/data" "$root/tests" -name '*.stl' -exec cp -n {} "$dir"/ \; ;;
        msh) cp -n "$root"/data/meshes/*.msh "$dir"/ ;;
        tetgen)
            # The target splits its input at the first NUL: .node text, NUL, .ele text.
            for node in "$root"/data/meshes/*.node; do
                local ele=${node%.node}.ele
                [ -f "$ele" ] && { cat "$node"; printf '\0'; cat "$ele"; } >"$dir/$(basename "${node%.node}")"
            done
            { printf '4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n'; printf '\0'
              printf '1 4 0\n0 0 1 2 3\n'; } >"$dir/single"
            ;;
        scene) cp -n "$root"/data/scenes/*.toml "$dir"/ ;;
    esac
}

failed=()
for target in "${targets[@]}"; do
    seed "$target"
    echo "== $target: $minutes min"
    # shellcheck disable=SC2086 # FUZZ_ARGS is a list of options
    if ! cargo fuzz run "$target" "corpus/$target" -- \
        -max_total_time=$((minutes * 60)) -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
        -print_final_stats=1 ${FUZZ_ARGS:-}; then
        failed+=("$target")
    fi
done
if [ ${#failed[@]} -gt 0 ]; then
    echo "failed: ${failed[*]} (inputs in fuzz/artifacts/)" >&2
    exit 1
fi
echo "all targets ran $minutes min without a failure"
