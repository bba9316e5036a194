"""What accuracy costs in time: analytic, fd3, fd5 and MuJoCo's transition derivatives, error
and median time over a sweep of steps, on six robots and two closed-loop mechanisms.

Usage: python validation/accuracy_vs_time.py [SYSTEM ...] [--repeats 5] [--out-dir DIR]
(the same as ``pinlin bench``). Writes validation/reports/accuracy_vs_time.md and the PNG plots
in validation/reports/accuracy_vs_time/.
"""

import sys

from pinlin.bench import main

if __name__ == "__main__":
    sys.exit(main())
