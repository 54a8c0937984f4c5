#!/usr/bin/env bash
# Regenerate every image under docs/ (the README shows docs/preview-cloth-40.png) with the release
# binary, so that no picture in the documentation is older than the program that draws it.
#
# Usage: scripts/docs-images.sh        (from anywhere; honours CARGO_TARGET_DIR)
#
# Each image is made in a temporary directory, copied beside its place in docs/ and renamed onto
# it: a reader never sees half an image, and an interrupted run leaves the old one. The script then
# checks that every PNG under docs/, and every PNG that README.md or a docs/ page shows, is one it
# made, and fails naming any other (an image nobody regenerates goes stale).
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
work=$(mktemp -d)
trap 'rm -rf "$work"; rm -f docs/.*.png.tmp' EXIT

hooke() { cargo run --release --quiet --bin hooke -- "$@"; }

made=()
# place SRC DEST: DEST's replacement, renamed onto it when complete.
place() {
    local tmp
    tmp="$(dirname "$2")/.$(basename "$2").tmp"
    cp "$1" "$tmp"
    mv -f "$tmp" "$2"
    made+=("$2")
    echo "wrote $2"
}

cargo build --release --quiet --bin hooke

# The README's picture: cloth-40 after its 100 frames (1 s), backward Euler by Newton.
hooke run cloth-40 --out "$work/cloth-40" --quiet
place "$work/cloth-40/preview.png" docs/preview-cloth-40.png

# docs/sph.md: the small dam break after 0.5 s, particles coloured by speed.
hooke run data/scenes/dam-break-small.toml --out "$work/dam-break-small" --quiet
place "$work/dam-break-small/preview.png" docs/preview-dam-break-small.png

# docs/editor.md: the last frame of the editor's golden build-and-pull script, replayed headless.
hooke edit --replay crates/editor/tests/scripts/build_and_pull.json --frames "$work/edit" \
    --every 119 --save "$work/edit/edited.toml"
place "$work/edit/frame_0119.png" docs/editor-build-and-pull.png

# Every image under docs/ and every image the Markdown shows must be one made above.
status=0
is_made() {
    local m
    for m in "${made[@]}"; do [[ "$m" == "$1" ]] && return 0; done
    return 1
}
for image in docs/*.png; do
    [[ -e "$image" ]] || continue
    if ! is_made "$image"; then
        echo "error: $image is not made by scripts/docs-images.sh (add it here or remove it)" >&2
        status=1
    fi
done
for page in README.md docs/*.md; do
    dir=$(dirname "$page")
    # Markdown images: ![alt](path.png)
    while IFS= read -r link; do
        path=$(realpath -m --relative-to="$root" "$dir/$link")
        if ! is_made "$path"; then
            echo "error: $page shows $link, which scripts/docs-images.sh does not make" >&2
            status=1
        fi
    done < <(grep -o '!\[[^]]*\]([^)]*\.png)' "$page" | sed 's/.*](\(.*\))/\1/')
done
exit $status
