#!/bin/sh
# Compile-check the libcamera camera backend (firmware/capture/src/libcamera.cpp) against the
# headers of other libcamera releases than the one installed: Raspberry Pi OS ships a newer
# libcamera than Debian 12's 0.0.3, and its API changes between releases (docs/capture.md).
# Each version's libcamera-dev package is downloaded from deb.debian.org into a scratch folder
# (nothing is installed) and the backend is compiled with -fsyntax-only against its headers.
#
#   tests/compat/libcamera_api.sh [SUITE ...]     default: bookworm-backports trixie sid
#
# Needs curl, xz, dpkg-deb, the C++ compiler and the OpenCV headers (`make deps`). Exit status:
# the number of suites whose headers the backend does not compile against.
set -u
cd "$(dirname "$0")/../.." || exit 1
MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
ARCH=$(dpkg --print-architecture)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
[ $# -gt 0 ] || set -- bookworm-backports trixie sid
failed=0
for suite in "$@"; do
  entry=$(curl -fsS "$MIRROR/dists/$suite/main/binary-$ARCH/Packages.xz" 2>/dev/null | xz -dq 2>/dev/null |
          awk '/^Package: libcamera-dev$/{p=1} p&&/^Version:/{v=$2} p&&/^Filename:/{print v, $2; p=0}')
  if [ -z "$entry" ]; then
    echo "$suite: no libcamera-dev in $MIRROR (network, or the suite has none)"
    failed=$((failed + 1))
    continue
  fi
  version=${entry%% *}
  file=${entry#* }
  dir="$WORK/$suite"
  mkdir -p "$dir"
  if ! curl -fsS -o "$dir/dev.deb" "$MIRROR/$file" || ! dpkg-deb -x "$dir/dev.deb" "$dir/root"; then
    echo "$suite: could not fetch or unpack $file"
    failed=$((failed + 1))
    continue
  fi
  if ${CXX:-c++} -std=c++20 -fsyntax-only -Wall -Wextra -DFS_HAVE_LIBCAMERA=1 \
      -I firmware/capture/include -I firmware/capture/src -I firmware/core/include -I firmware/config \
      -isystem /usr/include/opencv4 -isystem "$dir/root/usr/include/libcamera" \
      firmware/capture/src/libcamera.cpp 2>"$dir/log"; then
    warnings=$(grep -c "warning:" "$dir/log")
    echo "$suite: libcamera $version: compiles ($warnings warnings)"
  else
    echo "$suite: libcamera $version: DOES NOT COMPILE"
    grep "error" "$dir/log" | head -20
    failed=$((failed + 1))
  fi
done
exit "$failed"
