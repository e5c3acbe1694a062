# Small helpers shared by all targets.

# fs_warnings(<target>): the project's warning set, as a target property (no globals).
function(fs_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion
                         -Wno-sign-conversion)
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
