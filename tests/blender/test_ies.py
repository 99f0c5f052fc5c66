"""ies.py: IES files read as Cycles reads them (util/ies.cpp), their average about the axis
and its Legendre fit, against values written out here."""
import math

import numpy as np
import pytest

from airlight import ies


def text(polar, azimuth, candela, multiplier=1.0, ballast=1.0, lamp=1.0, kind=1, tilt="TILT=NONE"):
    rows = "\n".join(" ".join(f"{c:g}" for c in row) for row in np.atleast_2d(candela))
    return (f"IESNA:LM-63-2002\n[TEST] x\n{tilt}\n1 -1 {multiplier:g} {len(polar)} {len(azimuth)} {kind} 2 0 0 0\n"
            f"{ballast:g} {lamp:g} 100\n{' '.join(f'{v:g}' for v in polar)}\n{' '.join(f'{v:g}' for v in azimuth)}\n"
            f"{rows}\n")


def test01_values_are_cycles_units():
    polar, _, values = ies.parse(text([0, 90, 180], [0], [100, 50, 0], multiplier=2.0, ballast=0.5, lamp=0.8))
    np.testing.assert_allclose(values[0], np.array([100, 50, 0]) * 2.0 * 0.5 * 0.8 * 4.0 * math.pi / 177.83)
    np.testing.assert_array_equal(polar, [0, 90, 180])
    assert abs(ies.CANDELA_TO_WATT - 0.0706650768394) < 1e-12


def test02_tilt_include_is_skipped_and_commas_are_blanks():
    t = text([0, 90], [0], [10, 20], tilt="TILT=INCLUDE\n1\n3\n0 45 90\n1, 1, 1")
    np.testing.assert_allclose(ies.parse(t)[2][0], np.array([10, 20]) * ies.CANDELA_TO_WATT)


def test03_azimuth_average_is_the_trapezoid():
    # A quadrant 0..90 deg with a linear variation: the mean over the quadrant (Cycles mirrors it).
    profile = ies.axial(*ies.parse(text([0, 90], [0, 45, 90], [[0, 0], [1, 1], [2, 2]])))
    np.testing.assert_allclose(profile.values, [ies.CANDELA_TO_WATT] * 2)


def test04_fit_meets_the_accuracy_and_beyond_the_last_angle_is_dark():
    polar = np.arange(0, 90.1, 5.0)
    profile = ies.axial(*ies.parse(text(polar, [0], 100 * np.cos(np.radians(polar)))))
    c = np.linspace(-1, 1, 9)
    np.testing.assert_allclose(ies.sample(profile, c), np.where(c > 0, 100 * ies.CANDELA_TO_WATT * c, 0), atol=0.05)
    for accuracy in (0.05, 0.01, 0.002):
        fit = ies.fit(profile, accuracy)
        assert fit.mean_error <= accuracy or fit.degree == ies.MAX_DEGREE, (accuracy, fit)
    assert ies.fit(profile, 0.05).degree < ies.fit(profile, 0.002).degree
    # An exact polynomial is found exactly, in monomials.
    polar = np.arange(0, 180.1, 2.0)
    fit = ies.fit(ies.axial(*ies.parse(text(polar, [0], 3 + 2 * np.cos(np.radians(polar)) ** 2))), 1e-4)
    np.testing.assert_allclose(fit.coefficients[:3] / ies.CANDELA_TO_WATT, [3, 0, 2], atol=2e-3)


@pytest.mark.parametrize("bad, words", [
    ("no tilt here", "no TILT= line"),
    ("IESNA\nTILT=NONE\n1 -1 1 3", "header is truncated"),
    (text([0, 90], [0], [1, 2], kind=2), "type B is not in the fog"),
    (text([0, 90], [0], [1, 2])[:-6], "holds"),
    (text([90, 0], [0], [1, 2]), "not increasing"),
    (text([0, 90], [0], [0, 0]), None),
])
def test05_bad_files_are_refused_with_a_message(bad, words):
    with pytest.raises(ies.IESError, match=words or "all zero"):
        ies.fit(ies.axial(*ies.parse(bad)), 0.01)
