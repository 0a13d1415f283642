"""docs/table1.md and docs/results.md's Table I summary, rendered from the Monte Carlo records in docs/numbers/.

    magyro montecarlo paper-table1 --runs 50 --jobs 1 --method nls,ekf -o /tmp/mc50.json      (minutes)
    magyro montecarlo paper-table1 --runs 200 --jobs 1 -o /tmp/mc200.json                     (minutes)
    python docs/make_table1_numbers.py --record /tmp/mc50.json [--record200 /tmp/mc200.json]  keep them as records
    python docs/make_table1_numbers.py [--check] [PAGE]          rewrite (or check) docs/table1.md's blocks

docs/results.md's summary (`readme_blocks`) is rendered by docs/make_readme_numbers.py from the same record.

A record is `magyro montecarlo -o`'s JSON (schema magyro.montecarlo/1) without the per-run solver details, with
the command that made it. Every table is what `magyro.studies.montecarlo_table` makes of the record's runs: the
rows are recomputed from the runs' estimates and reported std (`table_rows`), and the text block is
`MonteCarloResult.table()`, as `magyro montecarlo` prints it. tests/test_doc_numbers.py checks that the pages
are what this script renders from the records and that a changed record changes them.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import doc_blocks  # noqa: E402
from doc_blocks import DOCS, fixed, fmt, read_record, table, write_record  # noqa: E402

PAGE = DOCS / "table1.md"
COMMAND = "python docs/make_table1_numbers.py"
RECORD = "montecarlo-paper-table1"          # 50 runs, nls and ekf on the same seeds
RECORD_200 = "montecarlo-paper-table1-200"  # 200 runs, nls
EULER = ("roll", "pitch", "yaw")
EKF_ROWS = ("R[0,0]", "R[2,2]", "h[0]", "h[2]")    # the magnetometer rows shown beside the gyro's


# --------------------------------------------------------------------------- the records


def condense(output: Path, command: str) -> dict:
    """`magyro montecarlo -o`'s JSON without the per-run solver details (the table needs estimates and std)."""
    d = json.loads(output.read_text(encoding="utf-8"))
    for m in d["methods"].values():
        for run in m["runs"]:
            run.pop("solver", None)
    d["command"] = command
    d["commit"] = doc_blocks.commit()
    return d


def result(record: dict, methods: tuple[str, ...] | None = None):
    """The record as a `MonteCarloResult`, its rows recomputed from the runs by `montecarlo_table.table_rows`."""
    from magyro.studies.montecarlo_output import MethodResult, MonteCarloResult
    from magyro.studies.montecarlo_table import table_rows
    from magyro.studies.montecarlo_values import Outcome, Parameter

    paper = record["paper_table1"]
    crlb = {k: (math.nan if v is None else v) for k, v in record["crlb"]["std"].items()}
    out = {}
    for name, m in record["methods"].items():
        if methods and name not in methods:
            continue
        params = [Parameter(p["name"], p["group"], p["unit"]) for p in m["parameters"]]
        outcomes = [Outcome(r["seed"], r["method"], r["ok"], r["seconds"], r.get("estimate", {}),
                            r.get("reported_std", {}), {}, r.get("error"), r.get("error_type"), r.get("exit_code"),
                            r.get("cpu_seconds", 0.0)) for r in m["runs"]]
        rows = table_rows(params, record["truth"], outcomes, crlb, paper["std"], paper["mean"])
        out[name] = MethodResult(name, rows, outcomes)
    return MonteCarloResult(
        problem=record["problem"]["name"], problem_source=record["problem"]["source"], runs=record["runs"],
        seed0=record["seeds"][0], jobs=record["jobs"], methods=out, truth=record["truth"], crlb=crlb,
        crlb_error=record["crlb"]["error"], paper_applies=paper["applies"], wall_s=record["wall_seconds"],
        start_method=record["start_method"], created=record["created"], mag_unit=record["problem"]["mag_unit"])


# --------------------------------------------------------------------------- the blocks of docs/table1.md


def gyro(rows):
    from magyro.studies.montecarlo_table import GYRO_GROUPS

    return [r for r in rows if r.group in GYRO_GROUPS]


def compared(rows):
    return [r for r in rows if r.paper_std is not None]


def label(name: str) -> str:
    if name.startswith("euler_deg["):
        return f"`{name}` ({EULER[int(name[10])]})"
    return f"`{name}`"


def names(rows) -> str:
    labels = [label(r.name) for r in rows]
    return "none" if not labels else labels[0] if len(labels) == 1 else ", ".join(labels[:-1]) + " and " + labels[-1]


def paper_number(r, value: float) -> str:
    """The paper's figure as Table I prints it: K_g to 4 decimals, bias and angles to 3; std 2 digits."""
    if value == r.paper_std and r.group != "euler_deg":
        return f"{value:.1e}".replace("e-0", "e-")
    return f"{value:.4f}" if r.group == "K_g" else f"{value:.3f}" if value == r.paper_mean else f"{value:g}"


def study_block(record: dict) -> str:
    res = result(record)
    ok = " and ".join(f"{m.method} {m.succeeded} of {record['runs']}" for m in res.methods.values())
    return (f"Produced on {record['created'][:10]} with magyro {record['magyro_version']} at commit "
            f"`{record['commit']}` by\n\n    {record['command'].replace('FILE', '/tmp/mc50.json')}\n\n"
            f"Runs that succeeded (seeds {res.seeds[0]}-{res.seeds[-1]}): {ok}.")


def beside_paper_block(record: dict) -> str:
    rows = compared(result(record, ("nls",))["nls"].rows)
    body = [[label(r.name), f"{r.truth:g}", paper_number(r, r.paper_mean), paper_number(r, r.paper_std), f"{r.mean:.6g}", fmt(r.std),
             fmt(r.crlb), fixed(r.std_over_crlb, 2), r.vs_paper] for r in rows]
    return table(["parameter", "truth", "paper mean", "paper std", "magyro mean", "magyro std", "CRLB", "std/CRLB",
                  "magyro std smaller?"], body, left=(0, -1))


def how_to_read_block(record: dict) -> str:
    rows = compared(result(record, ("nls",))["nls"].rows)
    yes = [r for r in rows if r.vs_paper == "yes"]
    forbids = [r for r in rows if r.vs_paper == "no (CRLB > paper)"]
    allows = [r for r in rows if r.vs_paper == "no (CRLB allows)"]
    lucky = [r for r in yes if r.crlb >= r.paper_std]
    n = result(record, ("nls",))["nls"].succeeded
    scatter = 1.0 / math.sqrt(2 * (n - 1))
    lines = [f"**yes**: magyro's std is smaller than the paper's: {len(yes)} of the {len(rows)} entries "
             f"({names(yes)})."
             + (f" For {names(lucky)} the CRLB is at or above the paper's std, so magyro is ahead there only through "
                f"the spread of {n} runs." if lucky else ""),
             f"**no (CRLB > paper)**: the CRLB is above the paper's std, so no unbiased estimator can match the paper "
             f"on this motion: {len(forbids)} of the {len(rows)} entries ({names(forbids)}).",
             f"**no (CRLB allows)**: the CRLB is below the paper's std, but magyro's std is not: "
             f"{len(allows)} {'entry' if len(allows) == 1 else 'entries'}"
             + ("." if not allows else
                " (" + "; ".join(f"{label(r.name)}: {fmt(r.std)} against the paper's {r.paper_std:g}, "
                                 f"{100 * (r.std / r.paper_std - 1):+.0f} %" for r in allows)
                + f"), where the sampling error of a {n}-run std is about {100 * scatter:.0f} %.")]
    return doc_blocks.notes(lines)


def paper_means_block(record: dict) -> str:
    rows = compared(result(record, ("nls",))["nls"].rows)
    off = {r.name: abs(r.paper_mean - r.truth) / r.paper_std for r in rows}
    worst = max(off, key=off.get)
    n = result(record, ("nls",))["nls"].succeeded
    magyro_worst = max(abs(r.mean_error_over_std) for r in gyro(result(record, ("nls",))["nls"].rows))
    return (f"The means differ more than the stds do. The paper's means are off the truth by up to {fmt(off[worst])} "
            f"of its own stds ({label(worst)}). With 50 runs (the paper's), that is {fmt(off[worst] * math.sqrt(50))} "
            f"standard errors of the mean, so the paper's filter was biased. magyro's means are within "
            f"{fmt(magyro_worst)} std of the truth on every gyro parameter ({n} runs).")


def full_table_block(record: dict) -> str:
    text = result(record, ("nls",)).table().splitlines()
    return "```\n" + "\n".join(line for line in text if not line.endswith("job(s)")) + "\n```"


def ekf_block(record: dict) -> str:
    res = result(record)
    nls, ekf = res["nls"], res["ekf"]
    rows = []
    lag = [n for n in ("time_offset_s",) if any(r.name == n for r in ekf.rows) and any(r.name == n for r in nls.rows)]
    for r in [*gyro(nls.rows), *(nls.row(n) for n in (*EKF_ROWS, *lag))]:
        e = ekf.row(r.name)
        rows.append([label(r.name), fmt(r.crlb), fmt(r.std), fixed(r.std_over_crlb, 2), fmt(e.std),
                     fixed(e.std_over_crlb, 2), fixed(e.mean_error_over_std, 2, sign=True),
                     fixed(e.reported_over_actual, 2)])
    above = [(r.name, r.std_over_crlb) for r in gyro(ekf.rows) if r.std_over_crlb > 1.10]
    mag = [ekf.row(n).std_over_crlb for n in EKF_ROWS]
    honest = [r.reported_over_actual for r in gyro(ekf.rows) if math.isfinite(r.reported_over_actual)]
    text = (f"All {ekf.succeeded} EKF runs of {res.runs} succeeded. The EKF leaves "
            + (", ".join(f"`{n}` ({v:.2f})" for n, v in above) or "no gyro parameter")
            + f" above 1.10 x CRLB; the magnetometer's R and h, fitted in step 1 without the gyro, are "
            f"{doc_blocks.span(mag, 1)} times the CRLB. Its mean reported std over the std actually observed "
            f"(`ekf rep/act`) is {min(honest):.2f}-{max(honest):.2f} on the gyro parameters.")
    if lag:
        t = ekf.row("time_offset_s")
        text += (f" The lag it estimates from its own likelihood (`time_offset_s`, true 0) scatters by "
                 f"{1e3 * t.std:.3g} ms, {t.std_over_crlb:.2f} x CRLB, and its std counts in every other one.")
    return text + "\n\n" + table(["parameter", "CRLB", "nls std", "nls std/CRLB", "ekf std", "ekf std/CRLB",
                                  "ekf err/std", "ekf rep/act"], rows, left=(0,))


def targets_block(record: dict) -> str:
    from magyro.studies.montecarlo_table import err_over_std_bound, std_ratio_interval

    m = result(record, ("nls",))["nls"]
    t = m.targets()
    n = m.succeeded
    lo, hi = std_ratio_interval(n)
    g = gyro(m.rows)

    def verdict(key):
        c = t[key]
        within = "all 12 within" if c["pass"] else f"{12 - len(c['failing'])} of 12 within; off: {', '.join(c['failing'])}"
        if not c.get("resolvable", True):   # as `montecarlo` says it: neither pass nor fail
            return f"**not resolvable** with {c['runs']} runs (needs {c['runs_needed']}); {within}"
        return "**pass**, all 12" if c["pass"] else f"**{12 - len(c['failing'])} of 12**; off: {', '.join(c['failing'])}"

    def worst(key, value_of):
        r = max(g, key=lambda r: abs(value_of(r) - (1.0 if key == "reported_over_actual" else 0.0)))
        return f"{abs(value_of(r)) if key == 'abs_mean_error_over_std' else value_of(r):.3f} (`{r.name}`)"

    rows = [["std / CRLB <= 1.10", verdict("std_over_crlb"), worst("std_over_crlb", lambda r: r.std_over_crlb)],
            ["\\|mean error\\| / std <= 0.3", verdict("abs_mean_error_over_std"),
             worst("abs_mean_error_over_std", lambda r: r.mean_error_over_std)],
            ["mean reported std / actual std in [0.8, 1.25]", verdict("reported_over_actual"),
             worst("reported_over_actual", lambda r: r.reported_over_actual)]]
    lines = [f"The sample std of {n} normal draws scatters by about {100 / math.sqrt(2 * (n - 1)):.0f} %. For an "
             f"efficient estimator, std/CRLB falls in [{lo:.2f}, {hi:.2f}] with 95 % probability, because "
             f"(n-1)s^2/sigma^2 ~ chi^2({n - 1}). On this run every gyro parameter's std/CRLB lies between "
             f"{doc_blocks.span([r.std_over_crlb for r in g], 2).replace('-', ' and ')}.",
             f"The mean error of an unbiased estimator stays below {err_over_std_bound(n):.2f} std with 95 % "
             f"probability (Student t with {n - 1} degrees of freedom, divided by sqrt({n})). The worst here is "
             f"{max(abs(r.mean_error_over_std) for r in g):.2f}."]
    for name in t["reported_over_actual"]["failing"]:
        r = m.row(name)
        reported = r.reported_over_actual * r.std
        lines.append(f"`{name}`: its sample std came out at {r.std_over_crlb:.2f} x CRLB (the 95 % range above is "
                     f"[{lo:.2f}, {hi:.2f}]) while the mean reported std is {fmt(reported)}, "
                     f"{reported / r.crlb:.2f} x the CRLB ({fmt(r.crlb)}): the ratio {r.reported_over_actual:.2f} "
                     "comes from the sample std, not from a wrong reported std.")
    return table(["target", "result", "worst"], rows, left=(0, 1)) + "\n\n" + doc_blocks.notes(lines)


def timing_block(record: dict) -> str:
    res = result(record)
    per = "; ".join(f"{m.method}: {record['methods'][m.method]['solve_seconds_mean']:.1f} s a solve wall, "
                    f"{record['methods'][m.method]['solve_cpu_seconds_mean']:.1f} s CPU"
                    for m in res.methods.values())
    return (f"Timing of the study above ({record['created'][:10]}, {res.jobs} job(s), this shared 2-core machine "
            f"under other sessions' load): {res.wall_s:.0f} s wall for {res.runs} runs of "
            f"{' and '.join(res.methods)}; {per}.")


def runs200_block(record: dict) -> str:
    m = result(record, ("nls",))["nls"]
    t = m.targets()
    g = gyro(m.rows)
    summary = table(["target (12 gyro parameters)", f"{m.succeeded} runs"], [
        ["std / CRLB <= 1.10", f"worst {max(r.std_over_crlb for r in g):.3f}"],
        ["\\|mean error\\| / std <= 0.3", f"worst {max(abs(r.mean_error_over_std) for r in g):.3f}"],
        ["mean reported std / actual std in [0.8, 1.25]",
         f"{doc_blocks.span([r.reported_over_actual for r in g], 2).replace('-', ' to ')}"]], left=(0, 1))
    rows = [[label(r.name), fmt(r.std), fmt(r.crlb), fixed(r.std_over_crlb, 2),
             "-" if r.group == "euler_deg" else fixed(r.reported_over_actual, 2), paper_number(r, r.paper_std)]
            for r in m.rows if r.paper_std is not None]
    paper = [r for r in m.rows if r.paper_std is not None]
    better, allows = [r for r in paper if r.vs_paper == "yes"], [r for r in paper if r.vs_paper == "no (CRLB allows)"]
    verdicts = ", ".join(f"{k}: {'pass' if c['pass'] else 'FAIL (' + ', '.join(c['failing']) + ')'}"
                         for k, c in t.items())
    return (f"`{record['command'].replace('FILE', '/tmp/mc200.json')}` ({record['created'][:10]}, commit "
            f"`{record['commit']}`; {verdicts}):\n\n" + summary + "\n\n"
            + table(["parameter", "std", "CRLB", "std/CRLB", "reported/actual", "paper std"], rows, left=(0,))
            + f"\n\nmagyro's std is smaller than the paper's Table I std on {names(better)}; larger although the "
            f"CRLB would allow smaller on {names(allows)}; on the others even the CRLB of this motion exceeds the "
            "paper's figure.")


def motion_block() -> str:
    """The stand-in motion of problems/paper-table1.toml."""
    from magyro.studies.scenario import load_problem

    m = load_problem("paper-table1").motion
    return f"{'/'.join(f'{a:g}' for a in m.amplitude_deg)} deg in {m.band_hz[0]:g}–{m.band_hz[1]:g} Hz"


def blocks(record: dict | None = None, record200: dict | None = None) -> dict[str, str]:
    record = record or read_record(RECORD)
    out = {"motion": motion_block(), "study": study_block(record), "beside-paper": beside_paper_block(record),
           "how-to-read": how_to_read_block(record), "paper-means": paper_means_block(record),
           "full-table": full_table_block(record), "ekf": ekf_block(record), "targets": targets_block(record),
           "timing": timing_block(record)}
    if record200 is not None or doc_blocks.has_record(RECORD_200):
        out["runs200"] = runs200_block(record200 or read_record(RECORD_200))
    return out


# --------------------------------------------------------------------------- docs/results.md's summary


def readme_blocks(record: dict | None = None) -> dict[str, str]:
    record = record or read_record(RECORD)
    g = gyro(result(record, ("nls",))["nls"].rows)
    return {"table1-summary": doc_blocks.notes([
        f"std/CRLB <= {max(r.std_over_crlb for r in g):.2f} for all 12 gyro parameters;",
        f"|mean error|/std <= {max(abs(r.mean_error_over_std) for r in g):.2f};",
        "the std a user reads (reported) over the actual spread: "
        f"{doc_blocks.span([r.reported_over_actual for r in g], 2)} ({record['runs']} runs at `{record['commit']}`)."])}


def main(argv: list[str]) -> int:
    for flag, name, command in (
            ("--record", RECORD, "magyro montecarlo paper-table1 --runs 50 --jobs 1 --method nls,ekf -o FILE"),
            ("--record200", RECORD_200, "magyro montecarlo paper-table1 --runs 200 --jobs 1 -o FILE")):
        if flag in argv:
            i = argv.index(flag)
            print(f"wrote {write_record(name, condense(Path(argv[i + 1]), command), compact=True)}")
            argv = argv[:i] + argv[i + 2:]
    return doc_blocks.main(argv, PAGE, lambda: blocks(), COMMAND)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
