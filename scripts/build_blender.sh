#!/usr/bin/env bash
# Builds a full, headless, patched Blender 4.3.2 (Debian's source, every cycles_patch/*.patch applied: the
# native closures, the Blender-side hook for the add-on's Neural Yarn BSDF node, and the OpenImageIO 2.4
# compatibility fix) into build/blender-full/bin/blender. NOT part of CI: about an hour on 2 cores (ccache
# makes rebuilds after a patch change a few minutes).
#
#   bash scripts/build_blender.sh          # -> build/blender-full/bin/blender
#
# Off, as Debian 12 cannot provide them or they are not needed to render: OSL, USD, MaterialX, Hydra,
# Vulkan, OpenVDB, audio, FFmpeg, OpenImageDenoise (renders must turn denoising off), GPU devices; and, as
# Blender's own lite configuration (build_files/cmake/config/blender_lite.cmake) turns them off, physics
# (Bullet, fluids, ocean), the CPU compositor, Freestyle, motion tracking, remeshers, OpenSubdiv, file
# formats other than .blend and images, translations.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
NYB="${NY_BUILD_DIR:-$ROOT/build}"
SRC="$NYB/blender-patched"
BUILD="$NYB/blender-full-build"
PREFIX="$NYB/blender-full"

# The verified, patched source tree (and the standalone Cycles, which the tests use anyway).
NY_BUILD_DIR="$NYB" bash "$ROOT/scripts/build_cycles.sh"

# Build dependencies: Debian's own for its Blender (bookworm's deb-src entry, added by
# fetch_blender_source.sh), a superset of what this configuration needs.
SUDO=()
[[ $(id -u) -eq 0 ]] || SUDO=(sudo)
if [[ ! -f "$NYB/.blender-build-deps" ]]; then
  echo "build_blender: installing Blender's build dependencies (apt-get build-dep blender)"
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get build-dep -y -qq blender > "$NYB/apt-build-dep.log" 2>&1 ||
    { echo "build_blender: apt-get build-dep blender failed (see $NYB/apt-build-dep.log)" >&2; exit 1; }
  touch "$NYB/.blender-build-deps"
fi

EMBREE_LIB=$(ls /usr/lib/*/libembree3.so | head -n1)
LAUNCHER=()
if command -v ccache > /dev/null; then
  LAUNCHER=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
# Configured every time (seconds when nothing changed), so that a change of these options reaches a build
# directory made before it.
cmake -S "$SRC" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release "${LAUNCHER[@]}" \
    -DWITH_HEADLESS=ON -DWITH_GHOST_X11=OFF -DWITH_GHOST_WAYLAND=OFF -DWITH_GHOST_SDL=OFF \
    -DWITH_CYCLES=ON -DWITH_CYCLES_OSL=OFF -DWITH_CYCLES_EMBREE=ON -DWITH_CYCLES_NATIVE_ONLY=ON \
    -DWITH_CYCLES_PATH_GUIDING=OFF -DWITH_CYCLES_DEVICE_CUDA=OFF -DWITH_CYCLES_DEVICE_OPTIX=OFF \
    -DWITH_CYCLES_DEVICE_HIP=OFF -DWITH_CYCLES_DEVICE_METAL=OFF -DWITH_CYCLES_DEVICE_ONEAPI=OFF \
    -DWITH_CYCLES_CUDA_BINARIES=OFF -DWITH_CYCLES_HYDRA_RENDER_DELEGATE=OFF \
    -DWITH_USD=OFF -DWITH_MATERIALX=OFF -DWITH_HYDRA=OFF -DWITH_VULKAN_BACKEND=OFF -DWITH_OPENVDB=OFF \
    -DWITH_AUDASPACE=OFF -DWITH_OPENAL=OFF -DWITH_SDL=OFF -DWITH_JACK=OFF -DWITH_PULSEAUDIO=OFF \
    -DWITH_PIPEWIRE=OFF -DWITH_CODEC_FFMPEG=OFF -DWITH_CODEC_SNDFILE=OFF -DWITH_OPENIMAGEDENOISE=OFF \
    -DWITH_INSTALL_PORTABLE=ON -DWITH_PYTHON_INSTALL=OFF -DWITH_PYTHON_INSTALL_NUMPY=OFF \
    -DWITH_PYTHON_INSTALL_ZSTANDARD=OFF -DWITH_LIBS_PRECOMPILED=OFF -DWITH_STRICT_BUILD_OPTIONS=OFF \
    -DEMBREE_LIBRARIES="$EMBREE_LIB" -DCMAKE_CXX_FLAGS="-DEMBREE_MAJOR_VERSION=3" \
    -DWITH_BULLET=OFF -DWITH_MOD_FLUID=OFF -DWITH_MOD_OCEANSIM=OFF -DWITH_MOD_REMESH=OFF -DWITH_QUADRIFLOW=OFF \
    -DWITH_COMPOSITOR_CPU=OFF -DWITH_FREESTYLE=OFF -DWITH_LIBMV=OFF -DWITH_OPENSUBDIV=OFF -DWITH_FFTW3=OFF \
    -DWITH_IK_ITASC=OFF -DWITH_UV_SLIM=OFF -DWITH_ALEMBIC=OFF -DWITH_OPENCOLLADA=OFF -DWITH_IO_PLY=OFF \
    -DWITH_IO_STL=OFF -DWITH_IO_WAVEFRONT_OBJ=OFF -DWITH_IO_GREASE_PENCIL=OFF -DWITH_DRACO=OFF \
    -DWITH_POTRACE=OFF -DWITH_HARU=OFF -DWITH_INTERNATIONAL=OFF -DWITH_INPUT_NDOF=OFF \
    -DCMAKE_INSTALL_PREFIX="$PREFIX" > "$NYB/blender-full-configure.log" ||
  { echo "build_blender: cmake failed (see $NYB/blender-full-configure.log)" >&2; exit 1; }
start=$(date +%s)
cmake --build "$BUILD" --target install
echo "build_blender: $PREFIX/blender built in $(( $(date +%s) - start )) s"
