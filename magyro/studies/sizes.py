"""How large a simulated problem may be (issue 25): every sample and sinusoid is held in memory, so a problem
file asking for 1e9 seconds, 1e9 Hz or 1e8 sinusoids is refused at once, naming the cap, instead of running
out of memory. The caps keep one simulation well under 1 GiB."""
from __future__ import annotations

from magyro.errors import InputError
from magyro.text import significant

MAX_RATE_HZ = 10_000.0           # faster than any gyro or magnetometer magyro calibrates
MAX_DURATION_S = 86_400.0        # a day
MAX_SAMPLES = 2_000_000          # per sensor: duration_s * rate_hz
MAX_COMPONENTS = 1_000           # sinusoids per motion factor
MAX_SINE_EVALUATIONS = 50_000_000   # samples * components: the multisine's (samples, components) arrays


def check_sizes(duration_s: float, rates_hz: dict, components: int, where: str) -> None:
    """InputError naming the cap when the problem is larger than a simulation may be."""
    if duration_s > MAX_DURATION_S:
        raise InputError(f"{where} [problem]: duration_s = {duration_s:g} is above the cap of {MAX_DURATION_S:g} s")
    for sensor, rate_hz in rates_hz.items():
        if rate_hz > MAX_RATE_HZ:
            raise InputError(f"{where} [{sensor}]: rate_hz = {rate_hz:g} is above the cap of {MAX_RATE_HZ:g} Hz")
        samples = duration_s * rate_hz
        if samples > MAX_SAMPLES:
            raise InputError(f"{where} [{sensor}]: duration_s x rate_hz = {significant(samples)} samples, above the cap of "
                             f"{MAX_SAMPLES:g} samples per sensor; shorten the problem or lower the rate")
    if components > MAX_COMPONENTS:
        raise InputError(f"{where} [motion]: components = {components} is above the cap of {MAX_COMPONENTS}")
    evaluations = components * duration_s * max(rates_hz.values())
    if evaluations > MAX_SINE_EVALUATIONS:
        raise InputError(f"{where} [motion]: components x samples = {significant(evaluations)}, above the cap of "
                         f"{MAX_SINE_EVALUATIONS:g}; use fewer components or fewer samples")
