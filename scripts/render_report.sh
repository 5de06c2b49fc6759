#!/usr/bin/env bash
# Renders an output folder's report.html in headless Chromium (Debian: apt-get install -y chromium)
# and fails when a figure is missing from what the browser drew.
#
#   scripts/render_report.sh OUT_DIR [SCREENSHOT.png]
#
# Checks, on the DOM as Chromium built it (--dump-dom): the number of inlined <svg> figures equals
# the page's <meta name="springfit-figures">, every SVG file in the folder is one of them, and
# every figure has drawn content; at 1200 px and at 500 px (a phone; the narrowest window headless Chromium draws) the page stays within the
# window and no figure is shrunk below 3/4 of its size. Writes a full-page screenshot (default OUT_DIR/report.png is NOT
# used, so the folder stays as springfit wrote it: /tmp/springfit-report-<folder>.png).
# Exit 0 ok, 1 a missing figure, 2 usage or no browser.
set -euo pipefail

dir=${1:?usage: scripts/render_report.sh OUT_DIR [SCREENSHOT.png]}
html="$dir/report.html"
shot=${2:-/tmp/springfit-report-$(basename "$(cd "$dir" && pwd)").png}
[[ -f $html ]] || { echo "render_report: $html: no such file" >&2; exit 2; }
browser=$(command -v chromium || command -v chromium-browser || command -v google-chrome || true)
[[ -n $browser ]] || { echo "render_report: no Chromium found (Debian: apt-get install -y chromium)" >&2; exit 2; }

url="file://$(cd "$dir" && pwd)/report.html"
flags=(--headless --no-sandbox --disable-gpu --hide-scrollbars --allow-file-access-from-files
       --user-data-dir="$(mktemp -d)" --virtual-time-budget=5000)
dom=$(mktemp)
"$browser" "${flags[@]}" --dump-dom "$url" >"$dom" 2>/dev/null

expected=$(sed -n 's/.*<meta name="springfit-figures" content="\([0-9]*\)".*/\1/p' "$dom" | head -1)
[[ -n $expected ]] || { echo "render_report: $html: no springfit-figures meta in the rendered DOM" >&2; exit 1; }
drawn=$(grep -o '<figure class="sf-figure"' "$dom" | wc -l)
svgs=$(grep -o '<svg' "$dom" | wc -l)
status=0
if [[ $drawn -ne $expected || $svgs -lt $expected ]]; then
  echo "render_report: $html: $drawn figures and $svgs <svg> elements in the DOM, expected $expected" >&2
  status=1
fi
for f in "$dir"/*.svg; do
  [[ -e $f ]] || continue
  name=$(basename "$f")
  if ! grep -q "data-file=\"$name\"" "$dom"; then
    echo "render_report: $html: figure $name is in the folder but not on the page" >&2
    status=1
  fi
done
# A figure with nothing drawn: an <svg> immediately closed.
if grep -q '<svg[^>]*>[[:space:]]*</svg>' "$dom"; then
  echo "render_report: $html: an empty <svg>" >&2
  status=1
fi

# Layout at a desktop width and at a phone width: the page itself must not run past the window
# (wide tables and figures scroll inside their own boxes), and no figure may be drawn smaller than
# 3/4 of its size (its text would be unreadable). A copy of the page with a measuring script is
# rendered; the page as written stays script-free.
probe=$(mktemp --suffix=.html)
sed 's|</body>|<script>addEventListener("load",()=>{const w=innerWidth,d=document.documentElement.scrollWidth;let s=1;for(const g of document.querySelectorAll("figure.sf-figure svg")){const n=g.width.baseVal.value;if(n>0)s=Math.min(s,g.getBoundingClientRect().width/n)}document.body.setAttribute("data-layout",`width ${w} scroll ${d} scale ${s.toFixed(3)}`)})</script></body>|' "$html" >"$probe"
for width in 1200 500; do
  layout=$("$browser" "${flags[@]}" --window-size=$width,900 --dump-dom "file://$probe" 2>/dev/null |
           sed -n 's/.*data-layout="\([^"]*\)".*/\1/p' | head -1)
  read -r _ w _ d _ scale <<<"${layout:-width 0 scroll 0 scale 0}"
  if [[ -z $layout ]]; then
    echo "render_report: $html at $width px: the layout could not be measured" >&2
    status=1
  elif (( d > w )); then
    echo "render_report: $html at $width px: the page is $d px wide, past the window's $w px" >&2
    status=1
  elif awk "BEGIN{exit !($scale < 0.75)}"; then
    echo "render_report: $html at $width px: a figure is drawn at $scale of its size" >&2
    status=1
  else
    echo "render_report: $html at $width px: fits (page $d px, figures at ≥ $scale of their size)"
  fi
done
rm -f "$probe"

# Full-page screenshot: the page height from the DOM is unknown to the CLI, so take a tall window.
height=$(( 1500 + 1000 * expected ))
(( height > 16000 )) && height=16000
"$browser" "${flags[@]}" --window-size=1100,"$height" --screenshot="$shot" "$url" >/dev/null 2>&1
[[ -s $shot ]] || { echo "render_report: Chromium wrote no screenshot" >&2; exit 1; }
echo "render_report: $html: $drawn of $expected figures rendered ($svgs <svg> elements); screenshot $shot"
rm -f "$dom"
exit $status
