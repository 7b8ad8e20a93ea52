#!/usr/bin/env bash
# Install headless Chromium (Debian's `chromium` package) for tests/viz/test_viz_browser.py.
# Idempotent and quick: does nothing when a Chromium binary is already on PATH.
# It installs only in CI (CI set): on a developer's machine it prints how to install
# and exits 0, and the browser test skips with that reason.
set -euo pipefail

for candidate in chromium chromium-browser google-chrome; do
    if command -v "$candidate" >/dev/null 2>&1; then
        echo "install_browser: $(command -v "$candidate") is already installed"
        exit 0
    fi
done

if [ -z "${CI:-}" ]; then
    echo "install_browser: Chromium not found; the browser test will skip." \
         "Install it with: sudo apt-get install chromium (or run with CI=1 to let this script do it)"
    exit 0
fi

if ! command -v apt-get >/dev/null 2>&1; then
    echo "install_browser: no apt-get here; install Chromium with your package manager" >&2
    exit 1
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
    SUDO="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq chromium
echo "install_browser: installed $(command -v chromium)"
