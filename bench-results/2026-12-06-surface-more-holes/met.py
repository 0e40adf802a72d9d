"""Quality targets of a sweep of the openmy / openmz sets against the peers of new/ (jobs/bench/surface_holes.py).

  python3 bench-results/2026-12-06-surface-more-holes/met.py SWEEP [BASE]
(from the repository root)"""
import os
import sys

sys.path.insert(0, "jobs/bench")
from surface_holes import compare  # noqa: E402

compare(sys.argv[1], os.path.join(os.path.dirname(os.path.abspath(__file__)), "new"), *sys.argv[2:3])
