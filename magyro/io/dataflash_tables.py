"""What every ArduPilot log reader gives (`magyro.io.dataflash_read`, `magyro.io.dataflash_zip`): the messages by
name and column, the parameters, the units the log states, the message counts and notes."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class LogTables:
    kind: str                                      # "DataFlash .bin", "Mission Planner .log", ...
    messages: dict = field(default_factory=dict)   # name -> {column -> array}
    parameters: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)      # name -> {column -> unit}, where the log says
    counts: dict = field(default_factory=dict)     # name -> messages in the log (all types)
    notes: list = field(default_factory=list)
