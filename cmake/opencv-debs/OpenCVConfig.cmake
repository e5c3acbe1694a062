# A minimal OpenCV package for the aarch64 cross build of the program: the arm64 OpenCV that
# cmake/arm64-debs.sh unpacked under FS_ARM64_DEBS (Debian 12's OpenCV 4.6; its own CMake files would
# need every OpenCV module's arm64 library, VTK and Qt among their dependencies). Used only through
# the aarch64 preset (OpenCV_DIR); defines the modules the program links, as imported targets.
if(NOT FS_ARM64_DEBS OR NOT EXISTS "${FS_ARM64_DEBS}/.complete")
  set(OpenCV_FOUND FALSE)
  set(OpenCV_NOT_FOUND_MESSAGE "FS_ARM64_DEBS (${FS_ARM64_DEBS}) holds no unpacked arm64 OpenCV: run cmake/arm64-debs.sh")
  return()
endif()
set(OpenCV_VERSION 4.6.0)
set(OpenCV_INCLUDE_DIRS "${FS_ARM64_DEBS}/usr/include/aarch64-linux-gnu/opencv4" "${FS_ARM64_DEBS}/usr/include/opencv4")
# The libraries these load (GDAL, BLAS, libav* ...) must be found at link time too: -rpath-link to every
# directory of the unpacked tree that holds shared libraries (the script's lib-dirs), on each target.
file(STRINGS "${FS_ARM64_DEBS}/lib-dirs" _fs_dirs)
list(JOIN _fs_dirs ":" _fs_dirs)
set(OpenCV_LIBS "")
foreach(m core imgproc imgcodecs calib3d videoio features2d flann)
  set(_lib "${FS_ARM64_DEBS}/usr/lib/aarch64-linux-gnu/libopencv_${m}.so.406")
  if(NOT EXISTS "${_lib}")
    set(OpenCV_FOUND FALSE)
    set(OpenCV_NOT_FOUND_MESSAGE "missing ${_lib} (cmake/arm64-debs.sh)")
    return()
  endif()
  if(NOT TARGET opencv_${m})
    add_library(opencv_${m} SHARED IMPORTED)
    set_target_properties(opencv_${m} PROPERTIES IMPORTED_LOCATION "${_lib}"
                          INTERFACE_INCLUDE_DIRECTORIES "${OpenCV_INCLUDE_DIRS}"
                          INTERFACE_LINK_OPTIONS "-Wl,-rpath-link,${_fs_dirs}")
  endif()
  set(OpenCV_${m}_FOUND TRUE)
  list(APPEND OpenCV_LIBS opencv_${m})
endforeach()
set(OpenCV_FOUND TRUE)
