#!/usr/bin/env bash
# Installs PACKAGE (and MORE packages with it) with apt-get unless PACKAGE is installed
# already; refreshes the package lists only when apt does not know PACKAGE (a fresh image).
# Needs root or sudo only when it installs. Shared by scripts/fetch-bench-meshes.sh and
# scripts/bench-peers.sh; WHO names the caller in its messages.
#
#   scripts/apt-ensure.sh WHO PACKAGE [MORE...]
set -euo pipefail
who="${1:?usage: apt-ensure.sh WHO PACKAGE [MORE...]}"
package="${2:?usage: apt-ensure.sh WHO PACKAGE [MORE...]}"
shift 2
if dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
  exit 0
fi
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "$who: run as root to install $package" >&2; exit 1; }
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
if ! apt-cache show "$package" >/dev/null 2>&1; then
  echo "$who: apt-get update"
  $sudo apt-get update -qq
fi
echo "$who: installing $package"
$sudo apt-get install -y -qq --no-install-recommends "$package" "$@"
