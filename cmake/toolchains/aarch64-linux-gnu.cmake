# Cross toolchain: Debian 12 host -> aarch64 Linux (Raspberry Pi 4/5 class robot computer).
#
# Uses Debian's packaged cross compiler (g++-aarch64-linux-gnu) and Debian multiarch for target
# libraries (libgtest-dev:arm64, libtomlplusplus-dev:arm64 ...), so no separate sysroot:
#   - the cross C library and libstdc++/libgomp come with the compiler: /usr/aarch64-linux-gnu
#   - multiarch :arm64 libraries and CMake package files: /usr/lib/aarch64-linux-gnu
#   - headers in /usr/include are architecture-independent (toml++, gtest); the arch-specific
#     multiarch headers would be in /usr/include/aarch64-linux-gnu.
# Tests run under qemu-user through CMAKE_CROSSCOMPILING_EMULATOR, so `ctest` works unchanged.
# Nothing here is machine-specific: all paths are Debian package paths.

set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)

set(FS_CROSS_TRIPLE aarch64-linux-gnu)
set(CMAKE_C_COMPILER   ${FS_CROSS_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${FS_CROSS_TRIPLE}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${FS_CROSS_TRIPLE})

# Search target files in the cross prefix first, then in the multiarch tree ("/" + lib/<arch>).
# find_package() looks in <prefix>/lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake before <prefix>/lib, so
# GTest resolves to /usr/lib/aarch64-linux-gnu/cmake/GTest (libgtest*.a for arm64), never to the
# x86_64 copy. Host programs (qemu, python, cmake -P helpers) are found outside the roots.
set(CMAKE_FIND_ROOT_PATH /usr/${FS_CROSS_TRIPLE} /)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# The cross compiler does not search /usr/include by default. Append it *after* the compiler's own
# (cross) system directories with -idirafter: header-only packages there (toml++, gtest) are found,
# but the x86_64 glibc headers in /usr/include can never shadow the aarch64 ones. Because the
# compiler then reports /usr/include as an implicit directory, CMake drops `-isystem /usr/include`
# from imported targets (GTest::gtest) and find_path() results, which would otherwise put it first.
set(CMAKE_C_FLAGS_INIT   "-idirafter /usr/include")
set(CMAKE_CXX_FLAGS_INIT "-idirafter /usr/include")

# OpenMP: the cross gcc ships libgomp (/usr/lib/gcc-cross/aarch64-linux-gnu/<ver>/libgomp.so,
# runtime in /usr/aarch64-linux-gnu/lib). FindOpenMP only compiles and links a probe and locates
# libgomp in the compiler's implicit link directories, so find_package(OpenMP) works unchanged.
# Under qemu it needs the LD_LIBRARY_PATH below like every threaded program.

# No run-time search path in the binaries: under qemu the libraries come from LD_LIBRARY_PATH below,
# and on the robot the program is built natively. (It also keeps CMake from warning that the unpacked
# arm64 libraries of FS_ARM64_DEBS could hide multiarch ones of the same name.)
set(CMAKE_SKIP_BUILD_RPATH ON)

# Run target binaries (tests, gtest discovery) under qemu-user.
#   -L /usr/aarch64-linux-gnu : the ELF interpreter and libraries of the cross toolchain.
#   LD_LIBRARY_PATH           : with libc6:arm64 installed (pulled in by libgtest-dev:arm64), the
#     cross ld.so would otherwise load /lib/aarch64-linux-gnu/libc.so.6 from the multiarch package,
#     a different glibc build than the loader; that mix hangs in pthread_create under qemu. Pin the
#     loader's search to the cross toolchain's own libc/libstdc++/libgomp.
# On an aarch64 host (building on the robot itself) the binaries run natively: no emulator.
#   FS_ARM64_DEBS (set by `make build-aarch64` when it builds the program too): the arm64 OpenCV,
#     libcamera and libgpiod that cmake/arm64-debs.sh unpacked there, after the toolchain's libraries.
#     Their directories are listed in FS_ARM64_DEBS/lib-dirs (written by the script; the linker gets
#     them from cmake/opencv-debs/OpenCVConfig.cmake).
set(_fs_debs_dirs "")
if(FS_ARM64_DEBS AND EXISTS "${FS_ARM64_DEBS}/lib-dirs")
  file(STRINGS "${FS_ARM64_DEBS}/lib-dirs" _fs_debs_list)
  list(JOIN _fs_debs_list ":" _fs_debs_dirs)
endif()
find_program(FS_QEMU_AARCH64 qemu-aarch64 qemu-aarch64-static)
if(FS_QEMU_AARCH64 AND NOT CMAKE_HOST_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
  set(_fs_ld_path /usr/${FS_CROSS_TRIPLE}/lib)
  if(_fs_debs_dirs)
    string(APPEND _fs_ld_path ":${_fs_debs_dirs}")
  endif()
  set(CMAKE_CROSSCOMPILING_EMULATOR
      ${FS_QEMU_AARCH64} -L /usr/${FS_CROSS_TRIPLE}
      -E LD_LIBRARY_PATH=${_fs_ld_path})
endif()
