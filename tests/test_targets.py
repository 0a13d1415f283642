"""One notion of "good enough" (issue 24): observe, report and batch judge one calibration of a real recording
(the shipped BROAD trial 2) against the same targets, read from one file, and all three verdicts move together
when the file changes; the refusal bound stays a separate notion."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from magyro.api import observe
from magyro.batch.limits import Limits, load_limits, verdict, with_targets
from magyro.batch.row import row_from_calibration
from magyro.errors import InputError
from magyro.observability.excitation import judge
from magyro.observability.report import accuracy_rows
from magyro.options import Options, StdBounds
from magyro.report.sections import calibration_section, parameter_rows
from magyro.targets import FILE_KEYS, KEYS, Targets, load_targets, resolve_targets

DOCS = Path(__file__).resolve().parent.parent / "docs"


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def targets_toml(t: Targets) -> str:
    return "[targets]\n" + "".join(f"{k} = {float(getattr(t, FILE_KEYS[k]))!r}\n" for k in KEYS)


@pytest.fixture(scope="module")
def observed(broad02_solved):
    """observe's report of broad-02 (no solve: the prediction at the initial estimate)."""
    session, _ = broad02_solved
    return observe(session, Options())


def observe_verdict(report, targets: Targets) -> str:
    """observe's own verdict function on observe's own prediction, against `targets`."""
    return judge(report.analysis, report.ellipsoid_problem, report.predicted_std, targets, Options().max_std,
                 report.prediction.get("field_disturbance"))[0]


GROUPS = ("scale", "nonorth", "bias", "misalignment")   # in the order of Targets' fields


def group_maxima(observed, cal) -> tuple[dict, dict]:
    """Per group, the largest one-sigma that observe predicts and that the calibration reports."""
    predicted = [float(np.max(v)) for _, v, _, _ in accuracy_rows(observed.predicted_std, Targets())]
    rows = parameter_rows(cal)
    solved = {g: max(r.std for r in rows if r.group == g) for g in GROUPS}
    return dict(zip(GROUPS, predicted)), solved


def test_observe_report_and_batch_move_together_with_the_targets_file(tmp_path, broad02_solved, observed):
    session, cal = broad02_solved
    row = row_from_calibration("broad-02", "broad-02.parquet", cal)
    predicted, solved = group_maxima(observed, cal)
    # a file whose targets are twice the largest std any command sees: all three say good enough
    loose = Targets(*(float(2 * max(predicted[g], solved[g])) for g in GROUPS))
    # ... and one at half the smaller of the two: all three say not
    tight = Targets(*(float(0.5 * min(predicted[g], solved[g])) for g in GROUPS))
    for targets, observe_word, report_word, batch_word in ((loose, "sufficient", "good", "accepted"),
                                                           (tight, "marginal", "fair", "rejected")):
        path = write(tmp_path / "targets.toml", targets_toml(targets))
        read = load_targets(path)
        assert read == targets
        assert observe_verdict(observed, read) == observe_word
        assert calibration_section(cal, None, read).status == report_word
        assert verdict(row, with_targets(None, read))[0] == batch_word
        # the batch's limits file with the same [targets] table judges the same way
        limits_path = write(tmp_path / "limits.toml", "[limits]\nmax_abs_bias_deg_s = 10\n\n" + targets_toml(targets))
        assert verdict(row, load_limits(limits_path))[0] == batch_word
        assert load_targets(limits_path) == targets            # observe/report read the very same file


def test_the_default_targets_call_broad02_marginal_everywhere(broad02_solved, observed):
    """A phone turned by hand for two minutes does not reach the defaults (1000 ppm, 0.01 deg/s ...): every
    command says so, naming the same targets."""
    _, cal = broad02_solved
    assert observed.targets == Targets() and observed.verdict == "marginal"
    section = calibration_section(cal)
    assert section.status == "fair" and "above the targets (1000 ppm scale" in section.sentence
    reason = verdict(row_from_calibration("d", "s", cal), with_targets(None, Targets()))
    assert reason[0] == "rejected" and ("> 1000 ppm" in reason[1] or "> 0.010 deg/s" in reason[1])


def test_the_refusal_bound_is_a_separate_looser_notion():
    t, b = Targets(), StdBounds()
    assert b.scale_ppm >= 10 * t.scale_factor_ppm and b.bias_deg_s >= 10 * t.bias_deg_s
    assert b.misalignment_deg >= 10 * t.misalignment_deg and b.nonorthogonality_deg >= 10 * t.non_orthogonality_deg
    assert load_targets(DOCS / "targets-example.toml") == Targets()   # the example shows the defaults
    example = load_limits(DOCS / "limits-example.toml")
    assert example.target_scale_ppm == load_targets(DOCS / "limits-example.toml").scale_factor_ppm


def test_command_line_numbers_override_the_file(tmp_path):
    path = write(tmp_path / "t.toml", "[targets]\ntarget_scale_ppm = 3000\ntarget_bias_deg_s = 0.05\n")
    assert resolve_targets(path) == Targets(scale_factor_ppm=3000.0, bias_deg_s=0.05)
    assert resolve_targets(path, None, 0.2) == Targets(3000.0, 0.2, 0.05, 0.1)
    assert resolve_targets(None, 500.0) == dataclasses.replace(Targets(), scale_factor_ppm=500.0)


@pytest.mark.parametrize("text, says", [
    ("[target]\ntarget_scale_ppm = 1\n", "unknown top-level key(s) target"),
    ("[limits]\nmax_abs_bias_deg_s = 1\n", "no [targets] table"),
    ("[targets]\nscale_ppm = 1000\n", "unknown key(s) scale_ppm; the keys are target_scale_ppm"),
    ("[targets]\nmax_std_scale_ppm = 1000\n", "max_std_* names the solve's refusal bound"),
    ("[targets]\ntarget_bias_deg_s = -0.01\n", "target_bias_deg_s must be a positive finite number"),
    ("[targets]\ntarget_bias_deg_s = 'small'\n", "target_bias_deg_s must be a number"),
    ("[targets]\ntarget_bias_deg_s = nan\n", "positive finite"),
    ("[targets]\nbias_deg_s = 0.1\ntarget_bias_deg_s = 0.1\n", "bias_deg_s is the old name of target_bias_deg_s"),
    ("targets = 3\n", "targets must be a [targets] table"),
    ("[targets\n", "not valid TOML"),
])
def test_an_unusable_targets_file_is_one_message(tmp_path, text, says):
    path = write(tmp_path / "t.toml", text)
    with pytest.raises(InputError) as e:
        load_targets(path)
    assert says in str(e.value) and str(path) in str(e.value)


def test_the_std_limits_are_set_in_one_place(tmp_path):
    both = write(tmp_path / "l.toml", "[limits]\ntarget_scale_ppm = 2000\n[targets]\ntarget_scale_ppm = 2000\n")
    with pytest.raises(InputError, match="set the same std targets twice"):
        load_limits(both)
    with pytest.raises(InputError, match="both set the std limits"):
        with_targets(Limits(target_scale_ppm=500.0), Targets())
    same = with_targets(Limits(target_scale_ppm=1000.0), Targets())   # the same file given twice: no conflict
    assert same.target_bias_deg_s == Targets().bias_deg_s


def test_every_command_takes_the_same_targets_options():
    from typer.testing import CliRunner

    from magyro.cli import app

    runner = CliRunner()
    for command in ("observe", "watch", "report", "batch"):
        res = runner.invoke(app, [command, "--help"], env={"COLUMNS": "200", "NO_COLOR": "1"})
        assert res.exit_code == 0
        for option in ("--targets", "--target-scale-ppm", "--target-nonorth-deg", "--target-bias-deg-s",
                       "--target-misalignment-deg"):
            assert option in res.output, (command, option)


def test_a_bad_targets_file_is_exit_2_before_any_work(tmp_path):
    from typer.testing import CliRunner

    from magyro.cli import app

    bad = write(tmp_path / "t.toml", "[targets]\nscale_ppm = 1\n")
    out = tmp_path / "o.json"
    session = Path(__file__).resolve().parent.parent / "data" / "broad-02.parquet"
    res = CliRunner().invoke(app, ["observe", str(session), "--targets", str(bad), "-o", str(out), "-q"])
    assert res.exit_code == 2 and "unknown key(s) scale_ppm" in res.output and not out.exists()


def test_one_vocabulary_targets_file_options_and_limits_file():
    """Before: scale_factor_ppm in a targets file, --target-scale-ppm, max_std_scale_ppm in a limits file (where
    max_std_* meant an acceptance target, and in solve --max-std-* the refusal bound). Now one name each: the
    acceptance targets target_* everywhere, max_std_* only the refusal bound."""
    from typer.testing import CliRunner

    from magyro.batch.limits import KEYS as LIMIT_KEYS
    from magyro.cli import app
    from magyro.targets import KEYS as TARGET_KEYS

    assert set(TARGET_KEYS) <= set(LIMIT_KEYS)
    assert not any(k.startswith("max_std_") for k in LIMIT_KEYS + TARGET_KEYS)
    for command in ("observe", "batch"):
        text = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "300", "NO_COLOR": "1"}).output
        for key in (k for k in TARGET_KEYS if not k.startswith("target_acc_")):   # the accelerometer's: file only
            assert f"--{key.replace('_', '-')}" in text, (command, key)
    solve = CliRunner().invoke(app, ["solve", "--help"], env={"COLUMNS": "300", "NO_COLOR": "1"}).output
    assert "--max-std-scale-ppm" in solve and "--target-scale-ppm" not in solve


def test_old_spellings_are_read_with_a_deprecation_message(tmp_path, run_magyro):
    from magyro.targets import DeprecatedKeyWarning

    def said(call):
        """What `call` returns and the deprecation messages it gave (each key its own)."""
        with pytest.warns(DeprecatedKeyWarning) as record:
            value = call()
        return value, " | ".join(str(w.message) for w in record)

    old_targets = write(tmp_path / "t.toml", "[targets]\nscale_factor_ppm = 3000\nnon_orthogonality_deg = 0.2\n")
    targets, messages = said(lambda: load_targets(old_targets))
    assert targets == Targets(scale_factor_ppm=3000.0, non_orthogonality_deg=0.2)
    assert "scale_factor_ppm is deprecated, read as target_scale_ppm" in messages
    assert "non_orthogonality_deg is deprecated, read as target_nonorth_deg" in messages
    old_limits = write(tmp_path / "l.toml", "[limits]\nmax_std_bias_deg_s = 0.05\nmax_std_acc_bias_m_s2 = 0.1\n")
    limits, messages = said(lambda: load_limits(old_limits))
    assert limits == Limits(target_bias_deg_s=0.05, target_acc_bias_m_s2=0.1)
    assert "max_std_acc_bias_m_s2 is deprecated, read as target_acc_bias_m_s2" in messages
    same, messages = said(lambda: Limits(max_std_bias_deg_s=0.05, max_std_acc_bias_m_s2=0.1))  # Python written before
    assert same == limits and "Limits(): max_std_bias_deg_s is deprecated" in messages
    value, messages = said(lambda: limits.max_std_bias_deg_s)
    assert value == 0.05 and "Limits.max_std_bias_deg_s is deprecated" in messages
    with pytest.raises(InputError, match="set the same std targets twice"), pytest.warns(DeprecatedKeyWarning):
        load_limits(write(tmp_path / "b.toml", "[limits]\nmax_std_scale_ppm = 9\n[targets]\ntarget_bias_deg_s = 1\n"))
    # on the command line: one plain line on stderr, and the command goes on (here to its own refusal)
    res = run_magyro("observe", tmp_path / "absent.parquet", "--targets", old_targets)
    lines = res.stderr.strip().splitlines()
    assert lines[0].startswith("magyro: targets file") and "scale_factor_ppm is deprecated" in lines[0], res.stderr
    assert "Warning" not in res.stderr and "no such file" in lines[-1] and res.returncode == 2
