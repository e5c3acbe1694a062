"""fuzzyctl — host tools for fuzzystereo.

Sub-modules, one job each:

* :mod:`fuzzyctl.errors`     — :class:`FatalError`, the one exception for user/device faults;
* :mod:`fuzzyctl.paths`      — where ``common/`` (FIS, config schema) and the firmware binary live;
* :mod:`fuzzyctl.fis`        — the FIS of eq. (10)-(12) / Table I, built with scikit-fuzzy;
* :mod:`fuzzyctl.config`     — TOML config loading, validated against ``common/config/schema.toml``;
* :mod:`fuzzyctl.firmware`   — running the ``fuzzystereo`` program (``fis eval``);
* :mod:`fuzzyctl.dump`       — reading/writing the stage dump of ``docs/formats.md``;
* :mod:`fuzzyctl.reference`  — the float64 desktop reference of the whole matcher;
* :mod:`fuzzyctl.compare`    — firmware dump vs reference, per stage, with tolerances;
* :mod:`fuzzyctl.cli`        — the ``fuzzyctl`` command line (thin: parses, calls, prints).
"""

__version__ = "0.1.0"
