"""Numerical stability suite (issue 3): every model at parameter extremes (gamma 0 and pi,
T from 1e-9 to 100, g near +-1, high polynomial orders, light on the view ray in front /
behind / at the eye, Dvp = inf). Every value is finite, and each is within the model's
stated error of an independent reference or equal to the analytic limit (stability_cases.py,
which benchmarks/stability_table.py prints as a markdown table)."""
import math

import pytest

import stability_cases

ROWS = stability_cases.all_rows()


def test01_every_value_is_finite():
    bad = [r.cells() for r in ROWS if not (math.isfinite(r.value) and r.value >= 0.0)]
    assert not bad, bad


def test02_the_table_covers_every_model():
    models = {r.model.split(" (")[0] for r in ROWS}
    for name in ("sun05", "sun05_exact", "quadrature", "biri06", "pegoraro10", "hoffman02", "baseline", "fogshop",
                 "pegoraro10 spot", "quadrature spot"):
        assert name in models, name
    cases = {r.case for r in ROWS}
    for case in ("T sweep", "T->0 limit", "gamma=0, light beyond surface", "gamma=pi, light behind eye",
                 "light on the ray, in front", "light at the eye"):
        assert case in cases


@pytest.mark.parametrize("row", ROWS, ids=[f"{r.model}|{r.case}|{r.params}" for r in ROWS])
def test03_within_stated_error_or_limit(row):
    assert row.passed, row.cells()
