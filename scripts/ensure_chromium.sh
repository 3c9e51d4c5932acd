#!/usr/bin/env bash
# Install Debian's Chromium for the report tests when it is missing (the tests skip, saying why,
# when it cannot be installed).
set -u
if command -v chromium >/dev/null 2>&1; then exit 0; fi
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
  echo "installing Debian's chromium for the report tests" >&2
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
    || echo "could not install chromium; the browser tests will be skipped" >&2
else
  echo "chromium not found and cannot be installed here (needs root and apt-get); browser tests will skip" >&2
fi
exit 0
