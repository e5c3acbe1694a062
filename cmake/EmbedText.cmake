# Script mode: -DIN=<text file> -DOUT=<cpp> -DSYMBOL=<name>
file(READ ${IN} content)
# Raw string literal with a delimiter that cannot appear in TOML.
file(WRITE ${OUT} "// Generated from ${IN} — do not edit.\n"
                  "extern const char* const ${SYMBOL};\n"
                  "const char* const ${SYMBOL} = R\"fs_embed(${content})fs_embed\";\n")
