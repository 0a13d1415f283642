"""Getting sessions in and out: session files, imports of real recordings, cutting, atomic output.

- `load_session(path)` reads and checks a session file (Parquet or CSV, docs/spec.md section 2);
  `write_session(session, path)` writes one; `write_imported` writes one with zstd.
  (`magyro.io.session_file`; the checks are `magyro.io.checks`, the column layout
  `magyro.io.columns`.)
- `import_broad`, `import_broad_movement`, `broad_movement_span`, `convert_broad`: BROAD
  benchmark trials (`magyro.io.broad`). `import_csv`: phone and logger CSV exports,
  `import_csv_files`: one CSV per sensor merged on time (`magyro.io.csv_import`; the text read by
  `magyro.io.csv_text`, units in `magyro.io.csv_units`, zips unpacked within caps by `magyro.io.csv_zip`);
  `guess_column_map`, `parse_column_map`, `parse_file_column_map`: which column is which (`magyro.io.csv_columns`);
  `import_preset`, `PRESETS`: the Sensor Logger and phyphox exports, `convert_csv`: `magyro import csv`
  (`magyro.io.csv_presets`).
- `trim`, `cut`, `decimate`: a session cut in time or rate (`magyro.io.cutting`).
- `write_text_atomically`, `write_atomically`: outputs that are whole or absent;
  `check_outputs(inputs, outputs)`: before any work, an output that is an input (or another
  output) or cannot be written is refused (`magyro.io.atomic`).

Every unusable input raises `magyro.errors.InputError` with one plain message.

Every name is imported on first use (module `__getattr__`): the importers need pandas
(and scipy for .mat files), which the solve path must not import (0.2-0.4 s each on every
run), and session files need pyarrow, which writing a JSON report does not.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from magyro.lazy import lazy_exports

_EXPORTS = {
    "load_session": "session_file", "write_session": "session_file", "write_imported": "session_file",
    "session_table": "session_file", "PARQUET_SUFFIXES": "session_file",
    "session_from_table": "checks", "MIN_SAMPLES": "checks", "MAX_PLAUSIBLE_RATE_RAD_S": "checks",
    "trim": "cutting", "cut": "cutting", "decimate": "cutting",
    "write_text_atomically": "atomic", "write_atomically": "atomic", "check_outputs": "atomic",
    "import_broad": "broad", "import_broad_movement": "broad", "broad_movement_span": "broad",
    "convert_broad": "broad", "BROAD_CITATION": "broad", "BROAD_LICENSE": "broad",
    "import_csv": "csv_import", "guess_column_map": "csv_columns", "parse_column_map": "csv_columns",
    "import_csv_files": "csv_import", "parse_file_column_map": "csv_columns",
    "import_preset": "csv_presets", "PRESETS": "csv_presets", "convert_csv": "csv_presets",
    "import_ulog": "ulog", "convert_ulog": "ulog",
    "import_rosbag": "rosbag", "convert_rosbag": "rosbag",
    "import_dataflash": "dataflash", "convert_dataflash": "dataflash",
}

__all__ = [  # = list(_EXPORTS), spelled out for linters
    "load_session", "write_session", "write_imported", "session_table", "PARQUET_SUFFIXES",
    "session_from_table", "MIN_SAMPLES", "MAX_PLAUSIBLE_RATE_RAD_S", "trim", "cut", "decimate",
    "write_text_atomically", "write_atomically", "check_outputs", "import_broad", "import_broad_movement",
    "broad_movement_span", "convert_broad", "BROAD_CITATION", "BROAD_LICENSE", "import_csv",
    "guess_column_map", "parse_column_map", "import_csv_files", "parse_file_column_map", "import_preset",
    "PRESETS", "convert_csv", "import_ulog", "convert_ulog", "import_rosbag", "convert_rosbag",
    "import_dataflash", "convert_dataflash",
]

if TYPE_CHECKING:
    from magyro.io.atomic import check_outputs, write_atomically, write_text_atomically
    from magyro.io.broad import (BROAD_CITATION, BROAD_LICENSE, broad_movement_span, convert_broad, import_broad,
                                 import_broad_movement)
    from magyro.io.checks import MAX_PLAUSIBLE_RATE_RAD_S, MIN_SAMPLES, session_from_table
    from magyro.io.csv_columns import guess_column_map, parse_column_map, parse_file_column_map
    from magyro.io.csv_import import import_csv, import_csv_files
    from magyro.io.csv_presets import PRESETS, convert_csv, import_preset
    from magyro.io.cutting import cut, decimate, trim
    from magyro.io.session_file import PARQUET_SUFFIXES, load_session, session_table, write_imported, write_session


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
