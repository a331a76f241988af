#!/usr/bin/env bash
# Builds the standalone `cycles` renderer from Debian's Blender 4.3.2 source with our patches applied.
#
#   bash scripts/build_cycles.sh            # -> build/cycles/bin/cycles (NY_BUILD_DIR overrides build/)
#
# A fresh build takes about 4 minutes on 2 cores (ccache makes rebuilds after a patch change quick).
#
# The source comes from scripts/fetch_blender_source.sh (verified sha256). The patches in
# cycles_patch/*.patch are applied in name order to a fresh copy of the tree whenever the patch set
# changes (a marker records the hash of the patch set), so the build always matches the checkout.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
NYB="${NY_BUILD_DIR:-$ROOT/build}"
PRISTINE="$NYB/blender-src"
SRC="$NYB/blender-patched"
BUILD="$NYB/cycles"

bash "$ROOT/scripts/fetch_blender_source.sh" "$PRISTINE"

# --- patch ---------------------------------------------------------------------------------------------
shopt -s nullglob
PATCHES=("$ROOT"/cycles_patch/*.patch)
PATCH_HASH=$( (echo "neuralyarn-patch-set-1"; for p in "${PATCHES[@]}"; do sha256sum "$p"; done) | sha256sum | cut -d' ' -f1)
if [[ ! -f "$SRC/.neuralyarn-patches" ]] || [[ "$(cat "$SRC/.neuralyarn-patches")" != "$PATCH_HASH" ]]; then
  echo "applying ${#PATCHES[@]} patch(es) to a fresh copy of the source"
  rm -rf "$SRC.tmp"
  # The tree's contents, not the path: a blender-src that is a link to a shared pristine tree would otherwise be
  # copied as the link, and the patches would change the shared tree through it.
  mkdir "$SRC.tmp"
  cp -a "$PRISTINE/." "$SRC.tmp/"
  for p in "${PATCHES[@]}"; do
    if ! patch -d "$SRC.tmp" -p1 --forward --quiet < "$p"; then
      echo "error: patch $(basename "$p") does not apply to blender 4.3.2+dfsg (is the source tree the verified one?)" >&2
      exit 1
    fi
  done
  echo "$PATCH_HASH" > "$SRC.tmp/.neuralyarn-patches"
  rm -rf "$SRC"
  mv "$SRC.tmp" "$SRC"
fi

# --- configure and build ---------------------------------------------------------------------------------
EMBREE_LIB=$(ls /usr/lib/*/libembree3.so | head -n1)
LAUNCHER=()
if command -v ccache > /dev/null; then
  LAUNCHER=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
if [[ ! -f "$BUILD/build.ninja" ]] || [[ "$(cat "$BUILD/.neuralyarn-patches" 2>/dev/null)" != "$PATCH_HASH" ]]; then
  cmake -S "$SRC" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release "${LAUNCHER[@]}" \
    -C "$SRC/build_files/cmake/config/cycles_standalone.cmake" \
    -DWITH_CYCLES_STANDALONE_GUI=OFF -DWITH_CYCLES_NATIVE_ONLY=ON \
    -DWITH_CYCLES_OSL=OFF -DWITH_CYCLES_PATH_GUIDING=OFF -DWITH_CYCLES_EMBREE=ON \
    -DWITH_CYCLES_DEVICE_CUDA=OFF -DWITH_CYCLES_DEVICE_OPTIX=OFF -DWITH_CYCLES_DEVICE_HIP=OFF \
    -DWITH_CYCLES_DEVICE_METAL=OFF -DWITH_CYCLES_DEVICE_ONEAPI=OFF -DWITH_CYCLES_CUDA_BINARIES=OFF \
    -DWITH_CYCLES_HYDRA_RENDER_DELEGATE=OFF -DWITH_USD=OFF -DWITH_MATERIALX=OFF \
    -DWITH_HYDRA=OFF -DWITH_OPENVDB=OFF -DWITH_OPENCOLORIO=OFF -DWITH_VULKAN_BACKEND=OFF \
    -DWITH_OPENSUBDIV=OFF -DWITH_ALEMBIC=OFF -DWITH_HEADLESS=ON \
    -DWITH_GHOST_X11=OFF -DWITH_GHOST_WAYLAND=OFF \
    -DEMBREE_LIBRARIES="$EMBREE_LIB" -DCMAKE_CXX_FLAGS="-DEMBREE_MAJOR_VERSION=3" \
    -DCMAKE_INSTALL_PREFIX="$BUILD/install"
fi
echo "$PATCH_HASH" > "$BUILD/.neuralyarn-patches"
cmake --build "$BUILD" --target cycles
echo "built $(find "$BUILD" -name cycles -type f -perm -u+x | head -n1)"
