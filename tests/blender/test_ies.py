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
    assert ies.fit(profile, 0.002).degree == 1   # c over the lit half, dark beyond 90 deg
    polar = np.arange(0, 180.1, 5.0)
    profile = ies.axial(*ies.parse(text(polar, [0], 100 * np.exp(3.0 * np.cos(np.radians(polar))))))
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


def test06_a_spot_fit_is_measured_inside_its_cone():
    # Smooth within 40 deg of the axis, a bright ring at 120 deg that the spot's cone hides.
    polar = np.arange(0, 180.1, 2.5)
    candela = 100 + 50 * np.cos(np.radians(polar)) + np.where(np.abs(polar - 120) < 10, 5000.0, 0.0)
    profile = ies.axial(*ies.parse(text(polar, [0], candela)))
    cone = (math.radians(70.0), 0.2)
    fit = ies.fit(profile, 0.002, cone)
    assert fit.mean_error <= 0.002 and fit.degree <= 3, fit
    assert ies.fit(profile, 0.002).degree > 8   # over the whole sphere the ring needs many more
    # The fit is what the fog gets: the error weighted by Cycles' spot factor, inside the cone.
    c = np.linspace(-1, 1, 4001)
    w = ies.cone_factor(c, *cone)
    miss = np.abs(np.polynomial.polynomial.polyval(c, fit.coefficients) - ies.sample(profile, c)) * w
    assert miss.mean() / (ies.sample(profile, c) * w).mean() <= 0.002
    np.testing.assert_allclose(ies.cone_factor([math.cos(math.radians(36.0)), 0.99, 1.0, 0.0], *cone),
                               [0.0, 0.99, 1.0, 0.0])
    with pytest.raises(ies.IESError, match="inside the spot's cone"):
        dark = ies.axial(*ies.parse(text(polar, [0], np.where(polar > 60, 100.0, 0.0))))
        ies.fit(dark, 0.01, cone)


def test07_a_profile_dark_past_an_angle_is_fitted_to_it():
    # A downlight: lit to 90 deg, dark beyond (the file's last angle), and one that falls to 0 at 60.
    polar = np.arange(0, 90.1, 2.5)
    down = ies.axial(*ies.parse(text(polar, [0], 1500 * np.cos(np.radians(polar)) ** 2)))
    assert ies.lit_extent(down) == 90.0
    fit = ies.fit(down, 0.001)
    assert fit.extent == pytest.approx(math.pi / 2) and fit.degree <= 6 and fit.mean_error < 1e-3, fit
    # Its mean over the sphere counts the dark half as dark.
    assert fit.mean == pytest.approx(0.5 * 1500 * ies.CANDELA_TO_WATT / 3.0, rel=2e-3)
    polar = np.arange(0, 180.1, 5.0)
    ramp = ies.axial(*ies.parse(text(polar, [0], np.maximum(0.0, 60.0 - polar))))
    assert ies.lit_extent(ramp) == 60.0
    assert ies.fit(ies.axial(*ies.parse(text(polar, [0], 1.0 + np.cos(np.radians(polar))))), 0.01).extent == math.pi


def test08_the_preview_draws_profiles_at_their_mean():
    from airlight import preview
    cone = (math.radians(90.0), 0.25)
    lights = dict(light_positions=np.zeros((1, 3)), light_intensities=np.ones((1, 3)),
                  spot_positions=np.arange(9.0).reshape(3, 3), spot_axes=np.tile([0.0, 0.0, -1.0], (3, 1)),
                  spot_intensities=np.full((3, 3), 2.0), spot_size=np.array([cone[0], math.pi, math.pi]),
                  spot_blend=np.array([cone[1], 0.0, 0.0]), spot_spread=np.full(3, math.pi),
                  spot_profiles=np.array([[1.0, 2.0], [0.0, 3.0], [0.0, 0.0]]),
                  spot_profile_in_cone=np.array([1.0, 0.0, 0.0]), spot_profile_extent=np.array([math.pi, 1.0, math.pi]))
    shadowed = dict(light_shadows=np.array([True]), spot_shadows=np.array([False, True, False]))
    preview._profiles_as_points(lights, shadowed)
    # The IES point light (row 1: 3c, lit within 1 rad) moves to the points at its mean over the sphere.
    np.testing.assert_allclose(lights["light_positions"], [[0, 0, 0], [3, 4, 5]])
    c1 = math.cos(1.0)
    np.testing.assert_allclose(lights["light_intensities"][1], 2.0 * 3.0 * (1 - c1 * c1) / 4.0, rtol=1e-4)
    assert shadowed["light_shadows"].tolist() == [True, True] and shadowed["spot_shadows"].tolist() == [False, False]
    # The spot with an IES keeps its cone, scaled by 1 + 2c weighted by its cone factor.
    c = np.linspace(math.cos(cone[0] / 2), 1.0, 20001)
    w = ies.cone_factor(c, *cone)
    np.testing.assert_allclose(lights["spot_intensities"][0], 2.0 * ((1 + 2 * c) * w).sum() / w.sum(), rtol=1e-3)
    np.testing.assert_allclose(lights["spot_intensities"][1], 2.0)   # the plain spot is untouched
    assert len(lights["spot_positions"]) == 2 and "spot_profiles" not in lights
