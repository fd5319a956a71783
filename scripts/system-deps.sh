#!/usr/bin/env bash
# Optional system packages, installed by `make demo` / `make test` on first use when we can:
#   libegl1 libegl-mesa0 libgl1-mesa-dri  -> MuJoCo offscreen rendering (EGL)
#   libosmesa6                            -> MuJoCo offscreen rendering fallback (OSMesa)
#   chromium                              -> the headless-browser test of report.html
# Never fatal: without them the render and browser tests skip and say why.
set -u
want=(libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6 chromium)
missing=()
for p in "${want[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
  echo "note: optional system packages missing (${missing[*]}); render/browser tests will skip" >&2
  exit 0
fi
echo "installing optional system packages: ${missing[*]}" >&2
{ apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"; } \
  >/dev/null 2>&1 || echo "note: could not install ${missing[*]}; render/browser tests will skip" >&2
exit 0
