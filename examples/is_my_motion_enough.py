"""Before solving: does the motion excite every gyro parameter, and how well? (magyro observe)

Three simulated recordings of the same length: a turn about one axis, two axes, and
the paper's three-axis motion. The theorem's ranks are 6, 9 and 12.

    python examples/is_my_motion_enough.py
"""
import magyro
from magyro.studies.scenario import load_problem
from magyro.studies.simulate import simulate

for name in ("axis-z", "two-axes", "paper-table1"):
    session, _ = simulate(load_problem(name), seed=1)
    report = magyro.observe(session)
    print(f"{name:13s} rank {report.rank:2d} of 12  verdict {report.verdict:12s} {' '.join(report.advice)[:90]}")
