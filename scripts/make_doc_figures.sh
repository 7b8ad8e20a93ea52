#!/usr/bin/env bash
# Regenerate the README's figure gallery (docs/img/fig_*.png and the meshcat screenshots)
# from the command line, so every picture in the docs comes from a named command.
#
#   bash scripts/make_doc_figures.sh            # about 30 s on 2 cores
#
# Runs the main job, the three study-1 studies and IK-path example A into a temporary folder, copies their
# PNG figures into docs/img/, and photographs three exported meshcat replays (the main
# job's, the Pareto sweep's and example A's) with headless Chromium (skipped, with a message, if Chromium is
# not installed: `CI=1 bash scripts/install_browser.sh` installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
img=docs/img

youbot-opt main --out "$out/main" > /dev/null
youbot-opt multistart --starts 50 --seed 0 --out "$out/multistart" --quiet > /dev/null
youbot-opt pareto --out "$out/pareto" --quiet > /dev/null
youbot-opt bounds --out "$out/bounds" --quiet > /dev/null
youbot-opt ikpath --example A --out "$out/ikpath" --no-progress > /dev/null 2>&1

cp "$out/main/trajectory.png" "$img/fig_trajectory.png"
cp "$out/main/arm.png" "$img/fig_arm.png"
cp "$out/multistart/convergence.png" "$img/fig_convergence.png"
cp "$out/multistart/multistart.png" "$img/fig_multistart.png"
cp "$out/pareto/pareto.png" "$img/fig_pareto.png"
cp "$out/bounds/bound_scaling.png" "$img/fig_bound_scaling.png"

chromium=""
for name in chromium chromium-browser google-chrome; do
    if command -v "$name" > /dev/null 2>&1; then chromium=$(command -v "$name"); break; fi
done
if [ -z "$chromium" ]; then
    echo "make_doc_figures: no Chromium; meshcat screenshots not updated" >&2
else
    shoot() {  # shoot PAGE SECONDS WIDTH HEIGHT PNG: the page seeked to t = SECONDS
        "$chromium" --headless --no-sandbox --disable-gpu --use-angle=swiftshader \
            --enable-unsafe-swiftshader --disable-quic --no-first-run \
            --disable-background-networking --disable-component-update --disable-sync \
            --hide-scrollbars "--user-data-dir=$out/profile" "--screenshot=$5" \
            "--window-size=$3,$4" --virtual-time-budget=3000 "file://$1#t=$2" \
            > /dev/null 2>&1
    }
    shoot "$(realpath "$out/main/replay.html")" 1.2 800 600 "$img/meshcat_replay_youbot.png"
    shoot "$(realpath "$out/pareto/replay.html")" 1.0 1000 560 "$img/fig_replay_pareto.png"
    shoot "$(realpath "$out/ikpath/replay.html")" 1.0 800 600 "$img/meshcat_replay_ikpath_a.png"
fi
ls -l "$img"/fig_*.png "$img"/meshcat_replay_*.png
