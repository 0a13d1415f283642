from magyro.ekf.filter import *  # noqa: F401,F403  (temporary while the EKF is split)
from magyro.ekf.filter import _norm_terms, _score_correction  # noqa: F401
