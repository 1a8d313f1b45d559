#!/usr/bin/env bash
# Regenerate every picture in README.md with the exact command written beside it there.
#
# The README is the single list: every `rayscope render ...` or `rayscope view ...` in an
# inline code span that writes into docs/images/ is run as written, from the repository's root
# (the viewer's under xvfb-run, on Mesa's software Vulkan driver), and every docs/images/
# picture the README shows must be written by one of them. So a picture cannot drift from its
# command: change the command in the README and run this script.
#
# Usage: scripts/docs-images.sh [--release]
#   --release  build rayscope with the release profile (the default, dev, is optimised too:
#              the images are the same bits, only the build differs)
# Needs the course's scene files (RAYSCOPE_ASSETS, else ../shared/scenes), and xvfb-run and
# mesa-vulkan-drivers for the viewer's pictures (see .ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."

profile=dev
case "${1:-}" in
    --release) profile=release ;;
    "") ;;
    *) echo "usage: $0 [--release]" >&2; exit 2 ;;
esac

cargo build --profile "$profile" --locked -p rayscope-cli --features viewer
target_dir=$(cargo metadata --format-version 1 --no-deps | sed -n 's/.*"target_directory":"\([^"]*\)".*/\1/p')
dir=$profile
[ "$profile" = dev ] && dir=debug
bin="$target_dir/$dir/rayscope"

# The commands, from the README's inline code spans, in order.
mapfile -t commands < <(grep -o '`rayscope \(render\|view\) [^`]*docs/images/[^`]*`' README.md | tr -d '`')
# The pictures the README shows.
mapfile -t pictures < <(grep -o '](docs/images/[^)]*)' README.md | sed 's/^](\(.*\))$/\1/' | sort -u)
[ ${#commands[@]} -gt 0 ] || { echo "no \`rayscope ... docs/images/...\` command in README.md" >&2; exit 1; }

for p in "${pictures[@]}"; do
    if ! printf '%s\n' "${commands[@]}" | grep -q -- " $p\( \|$\)"; then
        echo "README.md shows $p but gives no command that writes it" >&2
        exit 1
    fi
done

export WGPU_BACKEND="${WGPU_BACKEND:-vulkan}"
for c in "${commands[@]}"; do
    read -r -a words <<<"$c"
    echo "== $c"
    case "${words[1]}" in
        render) "$bin" "${words[@]:1}" ;;
        view) xvfb-run -a -s "-screen 0 1600x1000x24" "$bin" "${words[@]:1}" ;;
    esac
done
echo "== wrote ${#commands[@]} pictures"
