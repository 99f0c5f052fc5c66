#!/usr/bin/python3
"""Prints the numerical stability table of every model (issue 3) as markdown.

    /usr/bin/python3 benchmarks/stability_table.py [--failures-only]

The rows (parameters, value, reference, relative error, tolerance, PASS/FAIL) come from
tests/native/stability_cases.py, the same rows tests/native/test_stability.py asserts:
gamma at 0 and pi, optical thickness T from 1e-9 to 100, HG g near +-1, high polynomial
orders, the light on the view ray (beyond the surface, in front, behind the eye, at the eye),
Dvp = inf, for sun05 (table / exact), biri06 (each phase), pegoraro10 (point and spot),
the quadratures, hoffman02, the baseline fog and Fogshop.
"""
import argparse
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.environ.get("AIRLIGHT_NATIVE_DIR") or os.path.join(REPO, "addon", "airlight"))
sys.path.insert(0, os.path.join(REPO, "tests", "native"))

import stability_cases  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--failures-only", action="store_true")
    args = ap.parse_args()
    rows = stability_cases.all_rows()
    shown = [r for r in rows if not r.passed] if args.failures_only else rows
    print(stability_cases.markdown(shown))
    n_pass = sum(r.passed for r in rows)
    print(f"\n{n_pass} of {len(rows)} rows PASS; {len(rows) - n_pass} FAIL")


if __name__ == "__main__":
    main()
