#!/usr/bin/env bash
# Build the docs site and take screenshots of the home page, an env page and the results page with
# headless Chromium (Debian's chromium package: apt-get install chromium), to look at them as a
# reader would. Usage: bash docs/screenshots.sh [OUT_DIR] (default: site-screenshots).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-site-screenshots}"
site="$(mktemp -d)"
NO_MKDOCS_2_WARNING=1 mkdocs build --strict --quiet --site-dir "$site"
mkdir -p "$out"
for page in index envs/Scara-C11-v2/index comparison/index; do
    name="$(echo "${page%/index}" | tr / -)"
    chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --window-size=1280,1800 \
        --screenshot="$out/$name.png" "file://$site/$page.html" 2>/dev/null
    echo "$out/$name.png"
done
rm -rf "$site"
