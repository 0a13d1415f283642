"""What every command of `magyro` shares: one plain message and the exit code of docs/spec.md section 3
for every failure the user can fix (`fail`, `run_guarded`), `--version`, help shown as written
(`as_written`, `Command`), and the options several commands take alike (`--no-repair`, `--gyro-noise` with
its unit)."""
from __future__ import annotations

import inspect
import math
import os
import re

import typer
from typer.core import TyperCommand

from magyro import __version__
from magyro.errors import MagyroError
from magyro.options import Repairs

NO_REPAIR_HELP = (f"Turn a repair of the recording off: {', '.join(Repairs.NAMES)}, or all (repeat, or separate "
                  "by commas, for several; magyro check lists what each repairs).")


_MARKUP = re.compile(r"(\\*)(\[[a-z#/@][^[]*?])")


def escape(text: str) -> str:
    """`text` with rich's markup escaped, as rich.markup.escape does (rich 12-15), without importing rich at
    start-up (13 ms of every command's ~0.5 s; rich is imported when help or progress is shown)."""
    text = _MARKUP.sub(lambda m: f"{m.group(1)}{m.group(1)}\\{m.group(2)}", text)
    return text + "\\" if text.endswith("\\") and not text.endswith("\\\\") else text


def as_written(command):
    """`command` with its help texts shown as written: rich would take the [plot] of "magyro[plot]" for markup
    and print "magyro", and would break the summary where the docstring's lines break."""
    if command.__doc__:
        paragraphs = inspect.cleandoc(command.__doc__).split("\n\n")
        command.__doc__ = escape("\n\n".join(" ".join(p.split()) for p in paragraphs))
    for parameter in inspect.signature(command).parameters.values():
        if getattr(parameter.default, "help", None):
            parameter.default.help = escape(parameter.default.help)
    return command


# a gyro noise density in deg/s/sqrt(Hz) per unit people write it in (Kalibr and imu_tk: rad/s/sqrt(Hz);
# datasheets: mdps/sqrt(Hz), or an angle random walk in deg/sqrt(h) = 1/60 deg/s/sqrt(Hz))
GYRO_DENSITY_UNITS_DEG_S = {"deg/s/sqrt(Hz)": 1.0, "rad/s/sqrt(Hz)": math.degrees(1.0), "mdps/sqrt(Hz)": 1e-3,
                            "dps/sqrt(Hz)": 1.0, "deg/sqrt(h)": 1.0 / 60.0}


def _unit_key(unit: str) -> str:
    return unit.replace(" ", "").replace("√Hz", "sqrt(Hz)").replace("√h", "sqrt(h)").replace("°", "deg").lower()


def gyro_noise_density(value) -> float:
    """--gyro-noise: a number in deg/s/sqrt(Hz), or a number with one of GYRO_DENSITY_UNITS_DEG_S
    ("0.0002rad/s/sqrt(Hz)", "0.0002 rad/s/√Hz"); the value in deg/s/sqrt(Hz)."""
    if isinstance(value, float):
        return value
    found = re.fullmatch(r"\s*([-+0-9.eE]+)\s*(.*?)\s*", str(value))
    factors = {_unit_key(u): f for u, f in GYRO_DENSITY_UNITS_DEG_S.items()}
    try:
        density = float(found.group(1)) * factors[_unit_key(found.group(2) or "deg/s/sqrt(Hz)")]
    except (AttributeError, ValueError, KeyError):
        raise typer.BadParameter(f"{value!r} is not a noise density: a number in deg/s/sqrt(Hz), or a number with "
                                 f"one of the units {', '.join(GYRO_DENSITY_UNITS_DEG_S)}") from None
    return density   # its sign and size: checked by the API, as for a number given from Python


def gyro_noise_help(default: str) -> str:
    return (f"Gyro noise density: a number in deg/s/sqrt(Hz), or with its unit, e.g. 0.0002rad/s/sqrt(Hz) (units: "
            f"{', '.join(GYRO_DENSITY_UNITS_DEG_S)}). Default: {default}.")


class Command(TyperCommand):
    """A command whose usage line names its arguments as its help does (SESSION CALIB), not in braces."""

    def collect_usage_pieces(self, ctx):
        return [piece[1:-1] if piece.startswith("{") and piece.endswith("}") else piece
                for piece in super().collect_usage_pieces(ctx)]


def fail(message: str, code: int) -> None:
    from magyro.text import escaped   # a message may quote input: no control or bidi character reaches the terminal

    typer.echo(f"magyro: {escaped(message, keep_lines=True)}", err=True)
    raise typer.Exit(code)


def run_guarded(action, progress: bool = True):
    """Run `action`, turning magyro errors and I/O failures into a message and an exit code; its steps show as a
    live line on stderr when that is a terminal and `progress` (off with -q)."""
    from magyro.progress import showing

    try:
        with showing(enabled=progress):
            return action()
    except MagyroError as e:
        fail(str(e), e.exit_code)
    except OSError as e:
        fail(f"cannot write output: {e}", 1)
    except Exception as e:  # a bug: still one line, not a traceback, unless debugging
        if os.environ.get("MAGYRO_DEBUG"):
            raise
        fail(f"internal error ({type(e).__name__}: {e}); rerun with MAGYRO_DEBUG=1 for a traceback and please report it", 1)


def version_callback(value: bool):
    if value:
        typer.echo(f"magyro {__version__}")
        raise typer.Exit(0)


# the accuracy targets (magyro.targets), the same options on observe, watch, report and batch
TARGETS_OPTION = typer.Option(
    None, "--targets", help="Accuracy targets: a TOML file with a 'targets' table (docs/targets-example.toml; keys target_scale_ppm ..., "
    "the names of the --target-* options), the same file for observe, watch, report and batch. Without: the defaults (1000 ppm, 0.1 deg, 0.01 deg/s, 0.1 deg).")
TARGET_SCALE_OPTION = typer.Option(None, "--target-scale-ppm", min=0.0, help="One-sigma target of the gyro scale factors (K_g diagonal), ppm (the file's target_scale_ppm; overrides --targets; default 1000).")
TARGET_NONORTH_OPTION = typer.Option(None, "--target-nonorth-deg", min=0.0, help="... of the non-orthogonality (K_g off-diagonal), deg (default 0.1).")
TARGET_BIAS_OPTION = typer.Option(None, "--target-bias-deg-s", min=0.0, help="... of the gyro bias, deg/s (default 0.01).")
TARGET_MISALIGNMENT_OPTION = typer.Option(None, "--target-misalignment-deg", min=0.0, help="... of the gyro-magnetometer misalignment, deg (default 0.1).")
