"""The Sun 2005 F table choices of the bake (table_size, table_interpolation) against the
quadrature reference bake of the same scene, and their argument checks."""
import numpy as np
import pytest

import scene_floor as scene  # test_bake_passes.py's tiny floor scene

# Worst per-ray airlight error against the exact-F path, measured over random rays in
# native/homogeneous/sun05_nearest_test.cpp (AirlightErrorAgainstExactF), + 20 %.
MAX_ERROR = {
    (64, "nearest"): 9.26e-2, (128, "nearest"): 4.31e-2, (256, "nearest"): 2.22e-2,
    (512, "nearest"): 1.16e-2, (64, "bilinear"): 8.36e-3, (256, "bilinear"): 1.30e-3,
}


@pytest.fixture(scope="module")
def reference():
    return scene.bake(model="quadrature", aa_samples=1)["airlight"][..., 0]


def _errors(out, ref):
    a = out["airlight"][..., 0]
    mask = ref > 1e-6 * ref.max()
    return np.abs(a[mask] / ref[mask] - 1.0)


def test01_default_is_256_bilinear():
    a = scene.bake(aa_samples=1)
    b = scene.bake(aa_samples=1, table_size=256, table_interpolation="bilinear")
    np.testing.assert_array_equal(a["airlight"], b["airlight"])


@pytest.mark.parametrize("size,interp", sorted(MAX_ERROR))
def test02_table_choice_within_measured_error(reference, size, interp):
    e = _errors(scene.bake(aa_samples=1, table_size=size, table_interpolation=interp), reference)
    assert e.max() <= 1.2 * MAX_ERROR[(size, interp)] + 1e-5


def test03_nearest_is_coarser_than_bilinear(reference):
    # The setting reaches the kernel: nearest's error is well above bilinear's, and
    # halves (first order) from 64 to 256 samples.
    near64 = _errors(scene.bake(aa_samples=1, table_size=64, table_interpolation="nearest"), reference)
    near256 = _errors(scene.bake(aa_samples=1, table_size=256, table_interpolation="nearest"), reference)
    bil64 = _errors(scene.bake(aa_samples=1, table_size=64, table_interpolation="bilinear"), reference)
    assert near64.mean() > 5.0 * bil64.mean()
    assert near256.mean() < 0.5 * near64.mean()


@pytest.mark.parametrize("kw", [dict(table_size=4), dict(table_size=5000),
                                dict(table_interpolation="cubic")])
def test04_bad_table_arguments_raise(kw):
    with pytest.raises(ValueError):
        scene.bake(**kw)
