#!/usr/bin/env bash
# arm64-debs.sh ROOT — the arm64 libraries the fuzzystereo *program* links (OpenCV, libcamera,
# libgpiod) and everything they load at run time, unpacked under ROOT, for the cross build of the
# program (`make build-aarch64`: preset aarch64 with FS_BUILD_APP=ON) and its runs under qemu-aarch64
# (`make test-aarch64`).
#
# Why not multiarch packages as for the core: Debian 12's arm64 OpenCV cannot be installed beside
# the amd64 one (libgdal32 and others are not co-installable), so the packages are downloaded with
# apt and unpacked with `dpkg -x` into ROOT instead, touching nothing on the system. apt resolves the
# run-time closure against an empty package database for arm64 (a consistent set, alternatives
# chosen as on a fresh Pi); the -dev packages (headers, .so links, .pc files) are added without their
# dependencies. The C library, libstdc++, libgcc and libgomp are left out: the cross toolchain's own
# (/usr/aarch64-linux-gnu/lib) are used at link and run time (mixing the two glibc builds hangs under
# qemu, cmake/toolchains/aarch64-linux-gnu.cmake). ~190 MB, once; ROOT/.complete marks a finished run.
set -euo pipefail
ROOT=${1:?usage: arm64-debs.sh ROOT}
ROOT=$(realpath -m "$ROOT")
[[ -f $ROOT/.complete ]] && { echo "arm64-debs: $ROOT is complete"; exit 0; }

RUNTIME=(libopencv-core406 libopencv-imgproc406 libopencv-imgcodecs406 libopencv-calib3d406
         libopencv-videoio406 libcamera0.0.3 libgpiod2)
DEV=(libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopencv-calib3d-dev
     libopencv-videoio-dev libopencv-features2d-dev libopencv-flann-dev libcamera-dev libgpiod-dev)
SKIP='^(libc6|libc6-dev|libstdc\+\+6|libgcc-s1|libgomp1|gcc-12-base|libc-dev-bin|linux-libc-dev|libcrypt1|libcrypt-dev)$'

mkdir -p "$ROOT/debs" "$ROOT/state"
: > "$ROOT/state/status"
apt_arm64=(apt-get -q -o Dir::State::status="$ROOT/state/status" -o APT::Architecture=arm64
           -o APT::Architectures::=arm64 -o Debug::NoLocking=1 -o APT::Sandbox::User=root)

# The run-time closure, resolved by apt as for a fresh arm64 system.
# "Inst NAME (VERSION RELEASE [ARCH])": arm64 packages get ":arm64", architecture-independent ones none.
mapfile -t closure < <("${apt_arm64[@]}" -s --no-install-recommends install "${RUNTIME[@]}" |
                       awk '/^Inst /{n=$2; sub(/:arm64$/, "", n); a=$NF; gsub(/[][)]/, "", a); print n, a}')
(( ${#closure[@]} > 0 )) || { echo "arm64-debs: apt resolved nothing for ${RUNTIME[*]} (is arm64 enabled: dpkg --add-architecture arm64 && apt-get update?)" >&2; exit 1; }
want=()
for line in "${closure[@]}"; do
  read -r p a <<< "$line"
  [[ $p =~ $SKIP ]] && continue
  if [[ $a == all ]]; then want+=("$p"); else want+=("$p:arm64"); fi
done
for p in "${DEV[@]}"; do want+=("$p:arm64"); done
echo "arm64-debs: ${#want[@]} packages -> $ROOT"
(cd "$ROOT/debs" && apt-get -q -o APT::Sandbox::User=root download "${want[@]}" >/dev/null)
for deb in "$ROOT"/debs/*.deb; do dpkg -x "$deb" "$ROOT"; done
# Every directory that holds a shared library: besides usr/lib/aarch64-linux-gnu, the BLAS/LAPACK
# alternatives (usr/lib/aarch64-linux-gnu/blas, lapack; update-alternatives does not run here) and a
# few libraries in usr/lib. cmake/opencv-debs passes them to the linker (-rpath-link), the toolchain
# file to qemu.
find "$ROOT/usr/lib" "$ROOT/lib" -name '*.so*' \( -type f -o -type l \) -printf '%h\n' 2>/dev/null | sort -u > "$ROOT/lib-dirs"
touch "$ROOT/.complete"
echo "arm64-debs: done ($(du -sh "$ROOT" | cut -f1))"
