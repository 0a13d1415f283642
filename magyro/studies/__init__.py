"""Studies around the calibration, apart from it: what it is measured against.

    scenario        a simulated problem (TOML in problems/): sensors, their errors, the motion
    simulate        its sessions, with an analytic truth
    crlb            the Cramer-Rao lower bound of a simulated problem
    montecarlo      the Monte Carlo accuracy study (the paper's Table I), with
                    montecarlo_values (the rows), montecarlo_table (the statistics)
                    and montecarlo_output (JSON, CSV, the printed table)
    dead_reckoning  a calibration judged by dead reckoning: against truth quaternions, or
                    by the closure drift of a session that ends where it started

Nothing is imported here: each study pulls in what it needs.
"""
