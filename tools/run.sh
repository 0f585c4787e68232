#!/usr/bin/env bash
# autocal's entry points (see README.md):
#   tools/run.sh demo       simulate an urban log, calibrate it, evaluate against the truth
#   tools/run.sh test       run every test suite (ctest), excluding the labels "long" and "fuzz"
#   tools/run.sh sanitize   the unit tests built with ASan + UBSan (-DAUTOCAL_SANITIZE=ON)
#   tools/run.sh style [BASE]  clang-format check of the sources, and with BASE the commit
#                           subjects of BASE..HEAD (tools/check_style.sh, docs/contributing.md)
# Each one installs the Debian 12 packages it needs when they are missing (as root),
# configures a build in build/ (sanitize: build-asan/; or $AUTOCAL_BUILD_DIR) and builds it.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
jobs="$(nproc)"

packages=(
  cmake ninja-build g++ pkg-config
  libeigen3-dev libceres-dev libsuitesparse-dev libgoogle-glog-dev libgflags-dev
  libgtest-dev libgmock-dev libbenchmark-dev libyaml-cpp-dev libnanoflann-dev
  libgeographiclib-dev libbz2-dev liblz4-dev libzstd-dev libsqlite3-dev
  python3-dev pybind11-dev python3-numpy
)
# What tools/run.sh style needs instead (no build).
style_packages=(git clang-format)

# install_missing_packages [package...]: the given packages, by default ${packages[@]}.
install_missing_packages() {
  local missing=() wanted=("$@")
  [ ${#wanted[@]} -gt 0 ] || wanted=("${packages[@]}")
  for p in "${wanted[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "autocal: installing missing Debian packages: ${missing[*]}"
  if [ "$(id -u)" -ne 0 ]; then
    echo "autocal: need root to install them; run as root or: sudo apt-get install ${missing[*]}" >&2
    exit 1
  fi
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

# configure_and_build <default build dir> [cmake options...]: sets $build.
configure_and_build() {
  build="${AUTOCAL_BUILD_DIR:-$1}"
  shift
  cmake -S "$root" -B "$build" -G Ninja "$@"
  cmake --build "$build" -j "$jobs"
}

case "${1:-}" in
  demo)
    install_missing_packages
    configure_and_build "$root/build" -DCMAKE_BUILD_TYPE=Release
    out="${AUTOCAL_DEMO_DIR:-$build/demo}"
    rm -rf "$out/urban" "$out/result"
    "$build/tools/autocal_simulate" --scenario=urban --duration_s=60 --seed=1 --out="$out/urban"
    "$build/tools/autocal_calibrate" --dataset="$out/urban" --problem="$root/problems/urban_full.yaml" \
      --output="$out/result"
    "$build/tools/autocal_evaluate" --dataset="$out/urban" --result="$out/result"
    echo "report: $out/result/report.html"
    ;;
  test)
    install_missing_packages
    configure_and_build "$root/build" -DCMAKE_BUILD_TYPE=Release
    ctest --test-dir "$build" --output-on-failure -j "$jobs" -LE "long|fuzz"
    ;;
  sanitize)
    # Any sanitizer report fails its test: UBSan does not recover (-fno-sanitize-recover),
    # ASan stops at its first error and LeakSanitizer fails the program at exit. The
    # accuracy suites are left out as well: they take minutes under the sanitizers.
    install_missing_packages
    configure_and_build "$root/build-asan" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" -DAUTOCAL_SANITIZE=ON \
      -DAUTOCAL_BUILD_BENCHMARKS=OFF
    ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1}" \
      UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1}" \
      ctest --test-dir "$build" --output-on-failure -j "$jobs" -LE "long|fuzz|accuracy"
    ;;
  style)
    install_missing_packages "${style_packages[@]}"
    shift
    "$root/tools/check_style.sh" "$@"
    ;;
  *)
    echo "usage: tools/run.sh demo|test|sanitize|style [BASE]" >&2
    exit 2
    ;;
esac
