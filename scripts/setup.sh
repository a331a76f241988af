#!/usr/bin/env bash
# One-shot setup for a fresh Debian 12 (bookworm) machine, idempotent:
#   1. installs the Debian packages the project builds against (only those missing),
#   2. configures and builds everything in Release into build/,
#   3. runs the main job (unless --no-run): a knitted piece of 3-ply yarns in the five presets, rendered with
#      the native closure (patched Cycles) and the stock-Blender fallback, and a contact sheet, in out/showcase/
#      (scripts/showcase.py, ~1.5 min on 2 cores); with --with-maps also the fleece fiber's albedo table and
#      lobe picture, fresh radiance distribution maps and the shipped model checked against them.
#
#   bash scripts/setup.sh              # set up and run the main job
#   bash scripts/setup.sh --with-maps  # ... and the maps/model check
#   bash scripts/setup.sh --no-run     # set up only (used by scripts/test.sh)
#   bash scripts/setup.sh --with-bench # also what the side-by-side benchmarks compare against (PyTorch)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"
RUN_MAIN=1
WITH_MAPS=0
WITH_BENCH=0
for arg in "$@"; do
  case "$arg" in
    --no-run) RUN_MAIN=0 ;;
    --with-maps) WITH_MAPS=1 ;;
    --with-bench) WITH_BENCH=1 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "setup.sh: unknown argument '$arg'" >&2; exit 2 ;;
  esac
done

# --- 1. Debian packages -----------------------------------------------------------------------------
# Compiler and build tools; the libraries of the C++ core (Embree for ray-curve intersection,
# OpenImageIO/OpenEXR for images, TBB for threads, Eigen for linear algebra, nlohmann-json, CLI11);
# GoogleTest, Google Benchmark and header-only Boost.Math for the tests; a font for plot labels;
# python3-venv for the add-on's test environment; Debian's Blender 3.4.1 (Cycles without OSL), the
# oldest Blender the add-on supports, which its tests run, and numpy for it (the add-on needs it; the
# package does not depend on it); GNU time (/usr/bin/time) for the renders' peak memory (scripts/evaluate.sh,
# bench_*.sh); clang-14 for the kernel headers' device-mode compile check (its address spaces, tests/device);
# xvfb for the add-on's viewport tests (Workbench and Blender's interface need a display).
PACKAGES=(
  build-essential cmake ninja-build pkg-config git ccache
  libembree-dev libopenimageio-dev openimageio-tools libopenexr-dev libtbb-dev libeigen3-dev
  nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev libboost-dev
  fonts-dejavu-core
  python3-venv blender python3-numpy time
  clang-14
  xvfb xauth
)
# Benchmarks only, not the tests: PyTorch (CPU), what scripts/bench_training.sh measures the trainer against.
((WITH_BENCH)) && PACKAGES+=(python3-torch)
missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if ((${#missing[@]})); then
  echo "setup: installing ${#missing[@]} Debian package(s): ${missing[*]}"
  SUDO=""
  if [[ $(id -u) -ne 0 ]]; then
    command -v sudo >/dev/null || { echo "setup: need root or sudo to install packages" >&2; exit 1; }
    SUDO="sudo"
  fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "setup: all ${#PACKAGES[@]} Debian packages present"
fi

# --- 2. Build ----------------------------------------------------------------------------------------
LAUNCHER=()
command -v ccache >/dev/null && LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
if [[ ! -f "$BUILD/build.ninja" ]]; then
  cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release "${LAUNCHER[@]}"
fi
cmake --build "$BUILD"

# --- 2b. The patched standalone Cycles (cycles_patch/): Debian's Blender 4.3.2 source, verified --------
NY_BUILD_DIR="$BUILD" bash "$ROOT/scripts/build_cycles.sh"

# --- 2c. Python environment for the add-on and the evaluation harness (.venv): the bpy wheel (Blender 4.5
# as a module, Cycles with OSL; CPython 3.11 = Debian 12's python3), numpy, pytest, matplotlib; for
# scripts/evaluate.py NVIDIA's FLIP (flip-evaluator), scikit-image (SSIM) and the OpenEXR bindings (3.3+:
# the File API); Dask distributed for the add-on's frame farm (batch.py --frames); scipy for the kernel's cos²
# table (scripts/make_cos2_table.py, checked by CTest). bpy pinned to the 4.5 LTS
# series. ----
VENV="$ROOT/.venv"
PY_REQS=("bpy==4.5.*" "numpy" "scipy" "pytest>=7" "matplotlib>=3.6" "flip-evaluator" "scikit-image" "OpenEXR>=3.3"
         "dask[distributed]")
if [[ ! -x "$VENV/bin/python" ]]; then
  /usr/bin/python3 -m venv "$VENV"
fi
if ! "$VENV/bin/python" -c "import bpy, numpy, scipy.integrate, pytest, matplotlib, flip_evaluator, skimage, OpenEXR, distributed; OpenEXR.File" >/dev/null 2>&1; then
  echo "setup: installing ${PY_REQS[*]} into $VENV (the bpy wheel is ~350 MB)"
  "$VENV/bin/python" -m pip install -q --upgrade pip
  "$VENV/bin/python" -m pip install -q --progress-bar on "${PY_REQS[@]}"
fi
"$VENV/bin/python" - <<'PYEOF'
import bpy
assert bpy.app.build_options.cycles_osl, "the bpy wheel in .venv has no OSL in Cycles"
print(f"setup: .venv has bpy {bpy.app.version_string} (Cycles OSL on)")
PYEOF

# --- 3. Main job -------------------------------------------------------------------------------------
if ((RUN_MAIN)); then
  mkdir -p "$ROOT/out"
  "$VENV/bin/python" "$ROOT/scripts/showcase.py" --out "$ROOT/out/showcase"
fi
if ((RUN_MAIN && WITH_MAPS)); then
  "$BUILD/cpp_core/neuralyarn" fiber --preset fleece --out "$ROOT/out/fleece_fiber_lobe.png"
  # The radiance distribution maps of the default preset at the paper's resolution, from a short run
  # (the paper uses 50-100 M paths; pass --paths 1e8 for that, ~3.5 min on 2 cores).
  "$BUILD/cpp_core/neuralyarn" gather --preset fleece --paths 4e6 --seed 2 --out "$ROOT/out/fleece.nyrdm"
  # The shipped fleece model (models/fleece.json, baked by scripts/bake_models.sh from other seeds) checked
  # against these fresh maps: albedo, energies, sampling variance, and the maps next to the networks.
  "$BUILD/cpp_core/neuralyarn" check "$ROOT/models/fleece.json" --maps "$ROOT/out/fleece.nyrdm" \
    --image "$ROOT/out/fleece_model_vs_maps.png" --theta-i 45 --phi-i 0
fi
