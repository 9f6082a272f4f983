"""Floats in circsim's JSON and CSV outputs are written to 12 significant digits (circsim.record.jsonout)."""

import json
import math
import re

from circsim.cli import main
from circsim.record.jsonout import dumps, rounded


def test_rounding_keeps_meaning_and_drops_representation_error():
    assert dumps(86 * 0.1) == "8.6" and dumps(0.1 + 0.2) == "0.3"
    assert rounded(16.47253661001117) == 16.4725366100
    assert rounded(1.23456789e-7) == 1.23456789e-7  # small values keep their digits (significant, not decimal)
    assert rounded({"a": [2.3000000000000003, (1, True, None, "x")]}) == {"a": [2.3, [1, True, None, "x"]]}
    assert math.isnan(rounded(float("nan"))) and rounded(float("inf")) == float("inf")
    assert isinstance(rounded(3), int)


def test_run_json_has_no_float_noise(tmp_path, capsys):
    out = tmp_path / "run.json"
    assert main(["run", "scene1", "--set", "duration_s=3", "--set", "merger.roi_m=3", "--quiet",
                 "--json", str(out)]) == 0
    text = out.read_text()
    rec = json.loads(text)
    assert rec["robots"] and rec["realtime_factor"] > 0
    # 8.600000000000001 has 16 significant digits; a float written to 12 never has more than 12
    noisy = [x for x in re.findall(r"\d+\.\d+", text) if len(x.replace(".", "").lstrip("0")) > 12]
    assert not noisy, noisy[:5]
