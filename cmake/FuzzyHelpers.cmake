# Small helpers shared by all targets.

# fs_warnings(<target>): the project's warning set, as a target property (no globals).
function(fs_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion
                         -Wno-sign-conversion)
endfunction()

# fs_precompile_headers(target <header>...): precompile the heavy third-party and standard headers
#   most sources of a test program include (GoogleTest, Eigen, OpenCV, nlohmann/json). Compile time
#   only — `make test` builds three configurations on CI's two cores. Used for the test programs only:
#   on the program's own sources a 200 MB PCH cost more to load than it saved (session 54). Every
#   source still includes what it uses: configure with -DFS_PCH=OFF to build without them.
function(fs_precompile_headers target)
  if(FS_PCH)
    target_precompile_headers(${target} PRIVATE ${ARGN})
  endif()
endfunction()

# fs_glue_sources(file...) / fs_glue_target(target): compile glue code — the command line and the test
#   programs — at -O1 in optimised builds (the algorithm libraries keep the build type's -O3). Compile
#   time only: GCC's -O levels do not change floating-point results (no -ffast-math; contraction is off,
#   fs_same_float_everywhere), which the golden hash tests check natively and under qemu-aarch64; and
#   these sources' loops call the libraries, so the program's speed is unchanged (`fuzzystereo bench`).
#   Configure with -DFS_GLUE_O1=OFF to build them at the build type's level.
function(fs_glue_sources)
  if(FS_GLUE_O1 AND CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    set_property(SOURCE ${ARGN} APPEND PROPERTY COMPILE_OPTIONS $<$<CONFIG:Release,RelWithDebInfo>:-O1>)
  endif()
endfunction()
function(fs_glue_target target)
  if(FS_GLUE_O1 AND CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE $<$<CONFIG:Release,RelWithDebInfo>:-O1>)
  endif()
endfunction()

# fs_same_float_everywhere(target): the target's floating-point results the same on the robot (AArch64)
#   as on the desktop (x86-64, whose baseline has no FMA): no fused multiply-add contraction, and on
#   AArch64 Eigen's NEON packets without their explicit fused pmadd (vfmaq_f64, chosen when
#   __ARM_FEATURE_FMA is defined; without it vmlaq_f64, a multiply and an add). Checked end to end by
#   the golden tests (tests/cpp/golden.hpp), natively and under qemu-aarch64; docs/algorithm.md 7.
#   PUBLIC: every target that includes the library's headers compiles their inline and template code
#   (Eigen's products among it) the same way — the linker keeps one copy of each, from any object, and
#   a test binary whose own files fused took the fused copy (a 1-ulp track_eval difference on AArch64).
function(fs_same_float_everywhere target)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PUBLIC -ffp-contract=off)
    if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
      target_compile_options(${target} PUBLIC -U__ARM_FEATURE_FMA)
    endif()
  endif()
endfunction()

# fs_embed_text(<out_cpp> <symbol> <file>): turn a text file into a C++ source that defines
#   extern const char* const <symbol>; so the firmware binary carries its own defaults
#   (common/fis/fis.toml, common/config/*.toml) and needs no data files on the robot.
function(fs_embed_text out_cpp symbol file)
  add_custom_command(
    OUTPUT ${out_cpp}
    COMMAND ${CMAKE_COMMAND} -DIN=${file} -DOUT=${out_cpp} -DSYMBOL=${symbol}
            -P ${PROJECT_SOURCE_DIR}/cmake/EmbedText.cmake
    DEPENDS ${file} ${PROJECT_SOURCE_DIR}/cmake/EmbedText.cmake
    COMMENT "Embedding ${file}")
endfunction()
