#!/usr/bin/env bash
# Make sure headless Chromium (Debian's `chromium` package) is installed: the report-page tests
# open the comparison report in it. Does nothing when it is already there. Installing needs root
# and apt-get (CI runs as root); elsewhere it says what to install.
set -euo pipefail

for exe in chromium chromium-browser; do
  if command -v "$exe" >/dev/null 2>&1; then exit 0; fi
done

if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
  echo "ensure_chromium: error: Chromium is not installed and this is not root on a Debian-like system;" >&2
  echo "  install it yourself (Debian/Ubuntu: 'sudo apt-get install chromium'), then run the tests again" >&2
  exit 1
fi

echo "ensure_chromium: installing Debian's chromium package (headless browser for the report-page tests)"
export DEBIAN_FRONTEND=noninteractive
# A fresh machine may have no package lists yet; update once, and again only if the install fails.
if ! apt-get install -y -q --no-install-recommends chromium >/tmp/ensure_chromium.log 2>&1; then
  apt-get update -q >>/tmp/ensure_chromium.log 2>&1
  apt-get install -y -q --no-install-recommends chromium >>/tmp/ensure_chromium.log 2>&1 || {
    echo "ensure_chromium: error: 'apt-get install chromium' failed; its output:" >&2
    tail -20 /tmp/ensure_chromium.log >&2
    exit 1
  }
fi
command -v chromium >/dev/null 2>&1 || { echo "ensure_chromium: error: chromium still not on PATH" >&2; exit 1; }
echo "ensure_chromium: $(chromium --version 2>/dev/null)"
