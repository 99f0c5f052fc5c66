"""The compiled module loads and lists its models."""
import _native


def test01_version():
    assert isinstance(_native.__version__, str) and _native.__version__


def test02_models():
    models = _native.models()
    names = [name for name, _ in models]
    assert names[0] == "sun05"
    assert {"sun05", "sun05_exact", "quadrature"} <= set(names)
    for name, description in models:
        assert isinstance(description, str) and description


def test03_exception_type():
    assert issubclass(_native.BakeCancelled, Exception)
