"""docs/real-data.md sections 2 and 4, rendered from the records of benchmarks/std_on_real_data.py and
benchmarks/attached_magnets.py (docs/numbers/std-on-real-data.json, docs/numbers/attached-magnets.json).

    python benchmarks/std_on_real_data.py --out docs/numbers/std-on-real-data.json     (needs ../shared/data/broad)
    python benchmarks/attached_magnets.py --out docs/numbers/attached-magnets.json
    python docs/make_record_numbers.py                                                 rewrite the page's blocks

docs/make_record_numbers.py adds these blocks to the page's; tests/test_doc_numbers.py checks them.
"""
from __future__ import annotations

import numpy as np

import doc_blocks
from doc_blocks import RECORDS, fixed, fmt, has_record, read_record, span, table

STD_RECORD = "std-on-real-data"
MAGNETS_RECORD = "attached-magnets"
GROUP_LABELS = {"scale": "scale factors", "non-orthogonality": "non-orthogonality", "bias": "bias",
                "misalignment": "misalignment"}
MAGNET_LABELS = {"32": "32, 1 cm", "34": "34, 3 cm", "36": "36, 5 cm"}
BIAS_TARGET_DEG_S = 0.05   # the real-data issue's target: bias within this of the rest mean


def measured(record: dict) -> str:
    return f"measured on {record['date']} at commit `{record['commit']}`: `{record['command']}`"


# --------------------------------------------------------------------------- section 2: the std and the room


def std_table_block(record: dict) -> str:
    rows = [[t, f"{r['disturbance_percent']:.2f}, {r['correlation_time_s']:.1f}", f"{r['std_over_white_median']:.2f}",
             f"{r['split_rms_z']:.2f}", f"{r['split_rms_z_white']:.2f}"] for t, r in record["trials"].items()]
    return (f"M{measured(record)[1:]} ({record['seconds']:.0f} s on this shared machine):\n\n"
            + table(["trial", "field disturbance (% of field, correlation s)", "std / white std (median)",
                     "split-half RMS z, std", "..., white std"], rows, left=(0,)))


def std_summary_block(record: dict) -> str:
    from magyro.result.consistency import MAX_RMS_Z

    z = [r["split_rms_z"] for r in record["trials"].values()]
    passing = all(v <= MAX_RMS_Z for v in z)
    worst = {which: max(max(d[which].values()) for d in record["distortions"].values())
             for which in ("std", "std_white")}
    trials = ", ".join(record["distortions"])
    return ((f"The split-half check of every undisturbed trial now passes (it warns above {doc_blocks.g(MAX_RMS_Z)})"
             if passing else f"The split-half check warns above {doc_blocks.g(MAX_RMS_Z)}: RMS z {doc_blocks.span(z, 2)}")
            + f". Known distortions applied to trials {trials} are recovered within {fixed(worst['std'], 2)} std "
            f"({fixed(worst['std_white'], 2)} white std).")


def chi_square_block(record: dict) -> str:
    chi = record["day_b_chi_square"]
    limit = chi["limit_95"]
    within = [g for g in GROUP_LABELS if chi["std"][g] <= limit]
    beyond = [g for g in GROUP_LABELS if chi["std"][g] > limit]

    def listed(groups):
        return " and ".join(f"the {GROUP_LABELS[g]} ({chi['std'][g]:.1f}; white std {chi['std_white'][g]:.1f})"
                            for g in groups)

    factors = " and ".join(f"{np.sqrt(chi['std'][g] / 9):.1f}x" for g in beyond)
    text = (f"(9 degrees of freedom, 95 % point {limit:.1f}), is within the std for {listed(within) or 'no group'}"
            + (f", but not for {listed(beyond)}: across recordings the {' and '.join(GROUP_LABELS[g] for g in beyond)} "
               f"vary about {factors} more than one "
               "recording's std says" if beyond else ""))
    return text


# --------------------------------------------------------------------------- section 4: attached magnets


def walk_label(walk) -> str:
    return "constant" if walk is None else f"walk {walk:g} uT/sqrt(s)"


def magnets_intro_block(record: dict) -> str:
    u = record["undisturbed"]
    rests = np.concatenate([r["rest_bias_deg_s"] for r in record["rows"] if r.get("rest_bias_deg_s") is not None])
    return (f"`{record['command']}` ({record['date']}, commit `{record['commit']}`, {record['seconds']:.0f} s; "
            f"undisturbed trials' scale factors: mean {', '.join(f'{v:+.0f}' for v in u['scale_ppm_mean'])} ppm, "
            f"range {min(u['scale_ppm_min']):+.0f} to {max(u['scale_ppm_max']):+.0f} ppm; the magnet trials' rests: "
            f"bias {rests.min():+.2f} to {rests.max():+.2f} deg/s over the axes)")


def grouped(record: dict) -> list[tuple[str, list, dict]]:
    """The rows, with a trial's models that were refused for the same reason as one row: (trial, walks, row)."""
    out: list[tuple[str, list, dict]] = []
    for r in record["rows"]:
        last = out[-1] if out else None
        if (last and "refused" in r and last[0] == r["trial"] and last[2].get("refused") == r["refused"]):
            last[1].append(r["walk_ut_sqrt_s"])
        else:
            out.append((r["trial"], [r["walk_ut_sqrt_s"]], r))
    return out


def models(walks: list) -> str:
    if len(walks) == 1:
        return walk_label(walks[0])
    named = [walk_label(w) for w in walks]
    return ", ".join(named[:-1]) + " and " + named[-1]


def magnets_table_block(record: dict) -> str:
    rows, seen = [], set()
    for trial, walks, r in grouped(record):
        label = MAGNET_LABELS[trial] if trial not in seen else trial
        seen.add(trial)
        if "refused" in r:
            rows.append([label, models(walks), f"refused: {doc_blocks.escape(r['refused'])}", "", "", ""])
            continue
        rows.append([label, models(walks),
                     " ".join(f"{v:+.0f}" for v in r["scale_minus_undisturbed_ppm"]),
                     " ".join(f"{v:.0f}" for v in r["scale_std_ppm"]),
                     " ".join(f"{v:+.3f}" for v in r["bias_minus_rests_deg_s"]),
                     " ".join(fmt(v) for v in r["bias_std_deg_s"])])
    return table(["trial", "hard iron (solved with --force)", "scale - undisturbed mean (ppm)", "std (ppm)",
                  "bias - rests (deg/s)", "std (deg/s)"], rows, left=(0, 1))


def magnets_summary_block(record: dict) -> str:
    """Per trial and model: the worst scale factor off the undisturbed mean, in ppm and in its std."""
    lines = []
    for trial, walks, r in grouped(record):
        if "refused" in r:
            lines.append(f"{trial}, {models(walks)}: refused even with --force")
            continue
        off = np.abs(r["scale_minus_undisturbed_ppm"])
        z = off / np.asarray(r["scale_std_ppm"])
        lines.append(f"{trial}, {models(walks)}: scale factors at most {off.max():.0f} ppm "
                     f"({z.max():.1f} std) off the undisturbed mean, bias at most "
                     f"{np.max(np.abs(r['bias_minus_rests_deg_s'])):.3f} deg/s off the trial's rests")
    return doc_blocks.notes(lines)


def refusals_block(trials: dict) -> str:
    """How magyro's defaults end on the magnet trials (docs/numbers/broad-trials.json)."""
    parts = []
    for t in MAGNET_LABELS:
        r = trials["trials"].get(t)
        if r is None:
            continue
        parts.append(f"{t}: " + (f"refused (exit 3), \"{r['error'].split(':')[0]}\"" if "error" in r
                                 else f"solved with {len(r['warnings'])} warning(s)"))
    return "; ".join(parts)


def blocks(trials: dict) -> dict[str, str]:
    """The blocks of these records that exist (a page may be rendered before a record is measured)."""
    out = {"magnet-refusals": refusals_block(trials),
           "day-b-yaw": f"{trials['day_b_peak_to_peak']['misalignment_deg'][2]:.2f}"}
    if has_record(REFERENCE_RECORD):
        r = read_record(REFERENCE_RECORD)
        out.update({"ref-frames": reference_frames_block(r), "ref-ideal": ideal_block(r),
                    "ref-magnets": reference_magnets_block(r), **reference_prose(r), **fast_slow_blocks(r)})
    if (RECORDS / "trajectory-accuracy.json").is_file():
        t = read_record("trajectory-accuracy")
        z = [f"{v:.1f}" for v in t["broad_02"]["rms_z_per_axis"]]
        out["trajectory-z"] = (f"{', '.join(z[:-1])} and {z[-1]} (`python benchmarks/trajectory_accuracy.py`, "
                               f"{t['date']})")
    if has_record(STD_RECORD):
        s = read_record(STD_RECORD)
        out.update({"std-table": std_table_block(s), "std-summary": std_summary_block(s),
                    "day-b-chi-square": chi_square_block(s)})
    if has_record(MAGNETS_RECORD):
        m = read_record(MAGNETS_RECORD)
        out.update({"magnets-intro": magnets_intro_block(m), "magnets-table": magnets_table_block(m),
                    "magnets-summary": magnets_summary_block(m)})
    return out


# --------------------------------------------------------------------------- sections 3 and 4: the reference

REFERENCE_RECORD = "broad-reference"   # benchmarks/broad_reference.py --ideal-magnetometer --out
DAY_B = ("02", "05", "07", "09")


def reference_frames_block(rec: dict) -> str:
    d, table_ii = rec["day_b"], rec["paper_table_ii"]
    rows = [["gyro frame against the optical body, C_b_t (deg)", *(fixed(v, 2) for v in d["C_b_t_euler_deg"]), "-"],
            ["reference C_b_m = C_m_t^T C_b_t (deg)", *(fixed(v, 2) for v in d["C_b_m_euler_deg"]),
             doc_blocks.g(table_ii["misalignment_deg"])],
            ["same, with a linear field gradient fitted from the optical position (deg)",
             *(fixed(v, 2) for v in d["C_b_m_euler_deg_gradient"]), doc_blocks.g(table_ii["misalignment_deg"])]]
    return (f"M{measured(rec)[1:]}:\n\n"
            + table([f"day B ({', '.join(d['trials'])}), peak to peak", "x / roll", "y / pitch", "z / yaw",
                     "Table II"], rows, left=(0,)))


def reference_prose(rec: dict) -> dict[str, str]:
    d, t = rec["day_b"], rec["trials"]
    grad = [t[k]["mag"]["gradient"]["G_percent_per_m"] for k in d["trials"]]
    ideal = {k: r["ideal"]["scale_ppm"] for k, r in t.items() if "ideal" in r}
    magnets = [v for k in MAGNET_LABELS if k in ideal for v in ideal[k]]
    undisturbed = [v for k in ideal if k not in MAGNET_LABELS for v in ideal[k]]
    days = [k for k in DAY_B if "ideal" in t.get(k, {})]
    ideal_bias_p2p = np.ptp(np.array([t[k]["ideal"]["bias_deg_s"] for k in days]), axis=0)
    off = [k for k, r in t.items() if "ideal" in r and k not in MAGNET_LABELS
           and np.max(np.abs(np.asarray(r["ideal"]["bias_deg_s"]) - np.asarray(r["gyro"]["rest_bias_deg_s"])))
           > BIAS_TARGET_DEG_S]
    rests = np.array([t[k]["gyro"]["rest_bias_deg_s"] for k in d["trials"]])
    motion_x = [t[k]["gyro"]["bias_minus_rest_deg_s"][0] for k in d["trials"]]
    same_sign = all(v < 0 for v in motion_x) or all(v > 0 for v in motion_x)
    fit_rms = [r["mag"]["plain"]["rms_uT"] for k, r in t.items() if k not in MAGNET_LABELS]
    return {"ref-fit-rms": f"{span(fit_rms, 2)} uT",
            "ref-bias-scatter": f"{ideal_bias_p2p.min():.2f}-{ideal_bias_p2p.max():.2f} deg/s",
            "ref-bias-trials": (", ".join(off[:-1]) + " and " + off[-1]) if len(off) > 1 else (off[0] if off else "none"),
            "ref-rest-repeat": (f"{np.ptp(rests, axis=0).max():.3f} deg/s over day B (z: "
                                f"{', '.join(f'{v:.4f}' for v in rests[:, 2])})"),
            "ref-motion-minus-rest": (f"x {min(motion_x):+.2f} to {max(motion_x):+.2f} deg/s in "
                                      f"{'all ' if same_sign else ''}{len(motion_x)} day-B trials"
                                      + ("" if same_sign else ", not all of one sign")),
            "ref-gyro-still": f"{max(d['C_b_t_euler_deg']):.1f} deg",
            "ref-mag-moves": f"{max(d['C_b_m_euler_deg']):.1f} deg",
            "ref-gradient": f"{min(grad):.0f}-{max(grad):.0f} %",
            "ref-magnet-scales": f"{min(magnets):+.0f} to {max(magnets):+.0f} ppm",
            "ref-undisturbed-scales": f"{min(undisturbed):+.0f} to {max(undisturbed):+.0f} ppm"}


SLOW, FAST = ("02", "05"), ("07", "09")   # day B's slow and fast trials


def fast_slow_blocks(rec: dict) -> dict[str, str]:
    """Each slow trial's scale factor (mean over the three axes) minus each fast trial's: the windowed optical
    reference's (`gyro`) and magyro's with the ideal magnetometer (`ideal`); and the ideal one's spread over day B
    (peak to peak per axis, the largest)."""
    t = rec["trials"]

    def pairs(key):
        mean = {k: float(np.mean(t[k][key]["scale_ppm"])) for k in (*SLOW, *FAST)}
        return [mean[s] - mean[f] for s in SLOW for f in FAST]

    days = [k for k in DAY_B if "ideal" in t.get(k, {})]
    spread = np.ptp(np.array([t[k]["ideal"]["scale_ppm"] for k in days]), axis=0).max()
    return {"ref-fast-slow": (f"the windowed reference by {span(pairs('gyro'), 0)} ppm, magyro with the ideal "
                              f"magnetometer by {span(pairs('ideal'), 0)} ppm (mean over the three axes, each slow "
                              "trial against each fast one)"),
            "ref-ideal-spread": f"{spread:.0f} ppm"}


def ideal_block(rec: dict) -> str:
    t, table_ii = rec["trials"], rec["paper_table_ii"]
    days = [k for k in DAY_B if "ideal" in t.get(k, {})]

    def p2p(key):
        return np.ptp(np.array([t[k]["ideal"][key] for k in days]), axis=0)

    def verdict(values, limit):
        return f"{doc_blocks.g(limit)}: " + ("**met**" if np.all(values <= limit) else "not met")

    worst = {k: float(np.max(np.abs(np.asarray(r["ideal"]["bias_deg_s"]) - np.asarray(r["gyro"]["rest_bias_deg_s"]))))
             for k, r in t.items() if "ideal" in r and k not in MAGNET_LABELS}
    rows = [["scale (ppm)", *(f"{v:.0f}" for v in p2p("scale_ppm")), verdict(p2p("scale_ppm"), table_ii["scale_ppm"])],
            ["non-orthogonality xy xz yz (deg)", *(f"{v:.3f}" for v in p2p("nonorth_deg")),
             verdict(p2p("nonorth_deg"), table_ii["nonorth_deg"])],
            ["bias (deg/s)", *(f"{v:.3f}" for v in p2p("bias_deg_s")), verdict(p2p("bias_deg_s"), table_ii["bias_deg_s"])],
            [f"bias - rest mean, worst axis, trials {' / '.join(worst)} (deg/s)",
             " / ".join(f"{v:.3f}" for v in worst.values()), "", "", doc_blocks.g(BIAS_TARGET_DEG_S)]]
    return table([f"day B ({', '.join(days)}), peak to peak", "x", "y", "z", "Table II"], rows, left=(0,))


def reference_magnets_block(rec: dict) -> str:
    t = rec["trials"]
    rows = []
    for k, label in MAGNET_LABELS.items():
        if k not in t:
            continue
        m = t[k]["mag"]
        rows.append([label, f"{fmt(m['plain']['rms_uT'])} -> {fmt(m['h_spline']['rms_uT'])}",
                     " ".join(f"{v:.1f}" for v in m["h_spline"]["h_p2p_uT"])])
    und = [t[k]["mag"] for k in DAY_B if k in t]
    rows.append([f"undisturbed {DAY_B[0]}-{DAY_B[-1]}, for scale",
                 f"{span([m['plain']['rms_uT'] for m in und], 2)} -> {span([m['h_spline']['rms_uT'] for m in und], 2)}",
                 span([v for m in und for v in m["h_spline"]["h_p2p_uT"]], 1)])
    return table(["trial", "reference magnetometer RMS, constant h -> h every 3 s (uT)",
                  "h(t) peak to peak, x y z (uT)"], rows, left=(0, 1, 2))
