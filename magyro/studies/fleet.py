"""A fleet of simulated devices: one problem, many devices, each with its own sensor errors.

A problem file fixes the sensor errors of ONE device; its optional ``[spread]`` section
(`magyro.studies.scenario.Spread`, documented at the top of problems/paper-table1.toml)
says how much they vary from device to device. `device_scenario(problem, seed)` draws
device `seed` from it; `simulate_fleet` writes one session (and its truth) per device plus
a manifest, what `magyro simulate PROBLEM --seeds A-B -o DIR` does.

The draw. Device `seed` takes its errors from ``np.random.default_rng([seed, 1])``, a
stream separate from the noise of `simulate(problem, seed)` (``default_rng(seed)``) and
from the field disturbance (``[seed, 7]``). It draws 22 standard normals z, always all of
them and always in this order, so a spread set to 0 leaves the draws of the others as
they are:

    z[0:3]    K_g[i,i] (1 + 1e-6 scale_ppm z)                      i = 0, 1, 2
    z[3:6]    K_g[i,j] + radians(nonorthogonality_deg) z           (0,1), (0,2), (1,2)
    z[6:9]    bias_deg_s + bias_deg_s z
    z[9:12]   misalignment euler_deg + misalignment_deg z          roll, pitch, yaw
    z[12:15]  T[i,i] (1 + soft_iron z)                             i = 0, 1, 2
    z[15:18]  T[i,j] + soft_iron z                                 (0,1), (0,2), (1,2)
    z[18:21]  h + hard_iron z
    z[21]     time_offset_s + time_offset_s z

Below the diagonals K_g and T stay zero; the diagonals stay positive (the relative
spreads are at most 10 %, so it would take a draw beyond -10 sigma; that device is
refused rather than clipped). The motion is the problem's (``motion.seed``) for every
device. The noise of device `seed` is `simulate`'s noise of seed `seed`.

With no spread (or an all-zero one) `device_scenario(problem, seed)` is the problem
itself, and the fleet's sessions are exactly `simulate(problem, seed)`.
"""
from __future__ import annotations

import csv
import dataclasses
import io
import math
import os
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from magyro.errors import InputError
from magyro.studies.scenario import Scenario, Spread, load_problem

MAX_SEEDS = 100_000
DRAWS = 22          # standard normals per device, see the module docstring
UPPER_OFF = ((0, 1), (0, 2), (1, 2))
MANIFEST = "manifest.csv"


# --------------------------------------------------------------------------- seeds


def parse_seeds(text: str) -> list[int]:
    """`--seeds`: "3", "0-199" (inclusive) or "1,5,9" (items may be ranges: "1,5-7"), as a list of seeds.

    InputError on text that is none of these, negative seeds, an empty range (high < low),
    a seed given twice, or more than MAX_SEEDS seeds.
    """
    if not isinstance(text, str) or not text.strip():
        raise InputError("--seeds is empty; give a seed (3), an inclusive range (0-199) or a list (1,5,9)")
    spans = []
    for item in (part.strip() for part in text.split(",")):
        if item.startswith("-"):
            raise InputError(f"--seeds '{text}': seeds must be non-negative integers, got '{item}'")
        low_text, dash, high_text = item.partition("-")
        low = _seed(low_text, text)
        high = _seed(high_text, text) if dash else low
        if high < low:
            raise InputError(f"--seeds '{text}': the range {item} is empty (write it low-high, e.g. {high}-{low})")
        spans.append((low, high))
    total = sum(high - low + 1 for low, high in spans)
    if total > MAX_SEEDS:
        raise InputError(f"--seeds '{text}': {total} seeds, more than {MAX_SEEDS}; simulate the fleet in parts")
    seeds = [s for low, high in spans for s in range(low, high + 1)]
    if len(set(seeds)) != len(seeds):
        seen: set[int] = set()
        twice = next(s for s in seeds if s in seen or seen.add(s))
        raise InputError(f"--seeds '{text}': seed {twice} is given twice")
    return seeds


def _seed(part: str, text: str) -> int:
    part = part.strip()
    if part.startswith("-"):
        raise InputError(f"--seeds '{text}': seeds must be non-negative integers, got '{part}'")
    if not (part.isascii() and part.isdigit()):
        raise InputError(f"--seeds '{text}': expected a seed (3), an inclusive range (0-199) or a list (1,5,9); "
                         f"'{part}' is not a non-negative integer")
    return int(part)


# --------------------------------------------------------------------------- one device


def device_rng(seed: int) -> np.random.Generator:
    """The generator of device `seed`'s errors: separate from the noise (`default_rng(seed)`)."""
    return np.random.default_rng([seed, 1])


def device_scenario(problem: Scenario, seed: int) -> Scenario:
    """The problem with device `seed`'s sensor errors, drawn from its [spread] (the problem itself when none).

    The device has no spread of its own (it is one device). InputError when the draw
    breaks the problem's checks (a time offset beyond the duration) or a diagonal.
    """
    spread = problem.spread
    if spread.is_zero:
        return problem
    z = device_rng(seed).standard_normal(DRAWS)
    K_g = problem.K_g.copy()
    K_g[np.diag_indices(3)] *= 1.0 + 1e-6 * spread.scale_ppm * z[0:3]
    for (i, j), zk in zip(UPPER_OFF, z[3:6]):
        K_g[i, j] += math.radians(spread.nonorthogonality_deg) * zk
    T = problem.soft_iron.copy()
    T[np.diag_indices(3)] *= 1.0 + spread.soft_iron * z[12:15]
    for (i, j), zk in zip(UPPER_OFF, z[15:18]):
        T[i, j] += spread.soft_iron * zk
    device = dataclasses.replace(
        problem,
        K_g=K_g,
        gyro_bias_deg_s=problem.gyro_bias_deg_s + spread.bias_deg_s * z[6:9],
        misalignment_euler_deg=problem.misalignment_euler_deg + spread.misalignment_deg * z[9:12],
        soft_iron=T,
        hard_iron=problem.hard_iron + spread.hard_iron * z[18:21],
        mag_time_offset_s=problem.mag_time_offset_s + spread.time_offset_s * float(z[21]),
        spread=Spread(),
    )
    where = f"{problem.source_path or problem.name}: device {seed}"
    if np.any(np.diag(K_g) <= 0.0) or np.any(np.diag(T) <= 0.0):
        raise InputError(f"{where}: the draw from [spread] makes a diagonal of K_g or soft_iron non-positive")
    if abs(device.mag_time_offset_s) >= device.duration_s:
        raise InputError(f"{where}: the drawn time offset {device.mag_time_offset_s:g} s is not smaller than the "
                         "duration; make [spread] time_offset_s smaller")
    return device


# --------------------------------------------------------------------------- the fleet


def fleet_paths(problem: Scenario, seeds: Iterable[int], outdir) -> list[tuple[int, Path, Path]]:
    """(seed, session path, truth path) of every device: outdir/<name>-<seed:04d>.parquet and .truth.json."""
    from magyro.io.atomic import confined
    from magyro.text import file_name

    outdir = Path(outdir)
    name = file_name(problem.name, "the problem's name")   # it names files: no path in it, checked again below
    out = []
    for seed in seeds:
        session = confined(outdir, f"{name}-{seed:04d}.parquet")
        out.append((seed, session, session.with_name(session.stem + ".truth.json")))
    return out


def simulate_fleet(problem: Scenario | str | os.PathLike, seeds: Iterable[int], outdir,
                   progress: Callable[[int, int, Path], None] | None = None) -> list[Path]:
    """Per seed, the session of device `seed` (its errors from [spread], its noise from the seed) written to
    outdir/<name>-<seed:04d>.parquet with its truth beside it (<stem>.truth.json, this device's parameters),
    and outdir/manifest.csv (columns device_id, session; the session relative to outdir). Every file is
    written atomically; the outputs are checked before any work. `outdir` must exist.

    `progress(done, total, session_path)` is called after each device. Returns the session paths.
    """
    from magyro.io import check_outputs, write_session, write_text_atomically
    from magyro.studies.simulate import simulate, write_truth

    if not isinstance(problem, Scenario):
        problem = load_problem(problem)
    problem_path = problem.source_path or None   # the file it was read from: never overwritten
    seeds = list(seeds)
    if not seeds:
        raise InputError("no seeds: a fleet needs at least one device")
    outdir = Path(outdir)
    devices = fleet_paths(problem, seeds, outdir)
    manifest = outdir / MANIFEST
    check_outputs([problem_path], [manifest] + [p for _, s, t in devices for p in (s, t)])
    written = []
    for done, (seed, session_path, truth_path) in enumerate(devices, start=1):
        device = device_scenario(problem, seed)
        session, truth = simulate(device, seed)
        truth["device"] = {"seed": seed, "spread": problem.spread.to_dict(),
                           "draw": "numpy.random.default_rng([seed, 1]), see magyro.studies.fleet"}
        write_session(session, session_path)
        write_truth(truth, truth_path)
        written.append(session_path)
        if progress is not None:
            progress(done, len(devices), session_path)
    write_text_atomically(manifest, manifest_text([s.relative_to(outdir) for _, s, _ in devices]))
    return written


def manifest_text(sessions: list[Path]) -> str:
    """manifest.csv: device_id (the session's stem, NAME-SEED), session (its path relative to the manifest's
    folder, with /)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["device_id", "session"])
    for rel in sessions:
        writer.writerow([Path(rel).stem, Path(rel).as_posix()])
    return buf.getvalue()
