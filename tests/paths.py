"""Where the tests' files are: the repository, tests/data and the real map (one place, whatever a test's depth)."""

from pathlib import Path

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent
DATA = TESTS / "data"
REAL_MAP = DATA / "real-maps" / "turtlebot3_office.yaml"  # TurtleBot3 office (tests/data/real-maps/README.md)
