"""The imprecise-center experiment's report (issue 9): ``circsim.experiments.window_report`` as a script.

    python benchmarks/window_sweep_report.py runs/window-scene1 runs/window-scene2 --png docs/img/window_sweep.png
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from circsim.experiments.window_report import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
