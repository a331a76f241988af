#!/usr/bin/env bash
# Fetches and verifies Debian's Blender 4.3.2 source (the base of cycles_patch/), idempotently.
#
#   bash scripts/fetch_blender_source.sh [DEST]     # default DEST: build/blender-src
#
# 1. adds deb-src entries (bookworm for build dependencies, trixie for blender 4.3.2) if missing;
# 2. installs Cycles' build dependencies (a subset of `apt-get build-dep blender`, listed below);
# 3. downloads blender_4.3.2+dfsg.orig.tar.xz with `apt-get source --download-only`. The archive answers
#    404 for the .dsc, so apt exits 100 after fetching the tarballs; we therefore do not trust apt's exit
#    status but the orig tarball's sha256, which must be exactly the one below;
# 4. unpacks it into DEST (once; a marker file records the verified checksum).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
NYB="${NY_BUILD_DIR:-$ROOT/build}"
DEST="${1:-$NYB/blender-src}"
VERSION="4.3.2+dfsg-2"
ORIG="blender_4.3.2+dfsg.orig.tar.xz"
SHA256="1c748ccde3526c8bc617cec66ab8d16a9258f1ab509a4c2739f4a88611a3b89c"
DOWNLOAD="$NYB/downloads"

SUDO=()
if [[ $(id -u) -ne 0 ]]; then SUDO=(sudo); fi

# --- 1. source entries ---------------------------------------------------------------------------------
SRC_LIST=/etc/apt/sources.list.d/neuralyarn-src.sources
if [[ ! -f "$SRC_LIST" ]]; then
  echo "adding deb-src entries ($SRC_LIST)"
  "${SUDO[@]}" tee "$SRC_LIST" > /dev/null <<'SOURCES'
Types: deb-src
URIs: http://deb.debian.org/debian
Suites: bookworm
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb-src
URIs: http://deb.debian.org/debian
Suites: trixie
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SOURCES
  "${SUDO[@]}" apt-get update -qq
fi

# --- 2. build dependencies of standalone Cycles (all from bookworm) -------------------------------------
# Standalone Cycles without GUI, OSL, USD, OpenVDB, OCIO, path guiding: image I/O (OIIO, OpenEXR, Imath),
# Embree 3, TBB, pugixml (XML scenes), zstd, Boost headers, glog/gflags (logging), Eigen; epoxy is needed by
# the standalone app's display code even with the GUI off.
DEPS=(dpkg-dev xz-utils cmake ninja-build ccache libboost-dev libpugixml-dev libzstd-dev libopenimageio-dev
      libopenexr-dev libimath-dev libembree-dev libtbb-dev libeigen3-dev libgoogle-glog-dev libgflags-dev
      libepoxy-dev libpng-dev libjpeg-dev libtiff-dev)
MISSING=()
for p in "${DEPS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || MISSING+=("$p")
done
if ((${#MISSING[@]})); then
  echo "installing ${#MISSING[@]} build dependencies: ${MISSING[*]}"
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${MISSING[@]}" > /dev/null
fi

if [[ -f "$DEST/.neuralyarn-verified" ]] && [[ "$(cat "$DEST/.neuralyarn-verified")" == "$SHA256" ]]; then
  echo "blender source already unpacked and verified in $DEST"
  exit 0
fi

# --- 3. download and verify ----------------------------------------------------------------------------
mkdir -p "$DOWNLOAD"
if [[ ! -f "$DOWNLOAD/$ORIG" ]] || ! echo "$SHA256  $DOWNLOAD/$ORIG" | sha256sum -c --quiet 2>/dev/null; then
  echo "downloading blender $VERSION source (apt-get source; exit status 100 from the missing .dsc is expected)"
  (cd "$DOWNLOAD" && apt-get source --download-only "blender=$VERSION" > apt-source.log 2>&1) || true
fi
if [[ ! -f "$DOWNLOAD/$ORIG" ]]; then
  echo "error: $ORIG was not downloaded; see $DOWNLOAD/apt-source.log" >&2
  exit 1
fi
if ! echo "$SHA256  $DOWNLOAD/$ORIG" | sha256sum -c --quiet; then
  echo "error: $ORIG has sha256 $(sha256sum "$DOWNLOAD/$ORIG" | cut -d' ' -f1), expected $SHA256;" \
       "refusing to patch an unknown source tree" >&2
  exit 1
fi

# --- 4. unpack -----------------------------------------------------------------------------------------
rm -rf "$DEST.tmp"
mkdir -p "$DEST.tmp"
echo "unpacking into $DEST"
tar -xf "$DOWNLOAD/$ORIG" -C "$DEST.tmp" --strip-components=1
echo "$SHA256" > "$DEST.tmp/.neuralyarn-verified"
rm -rf "$DEST"
mv "$DEST.tmp" "$DEST"
echo "blender source verified ($SHA256) and unpacked in $DEST"
