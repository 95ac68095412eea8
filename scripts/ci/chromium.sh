# Sourced by .ci/run (bash, set -euo pipefail, root, Debian 12): Debian's Chromium for the operator-page
# test, which Playwright drives as the system browser (never `playwright install`: no downloads from CI).
if ! command -v chromium >/dev/null 2>&1; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq chromium >/dev/null
fi
export DOORLOC_CHROMIUM=/usr/bin/chromium
echo "chromium: $("$DOORLOC_CHROMIUM" --version 2>/dev/null || echo missing)"
