"""Builds the installable add-on zip (Blender: Preferences > Add-ons > Install...).

    python3 tools/package.py build/airlight.zip      (what `make package` runs)

The zip holds one folder, airlight/: the add-on's Python modules, its compiled _native
module (build it first: `make build`) and the GLSL sources of shaders/ in
airlight/shaders/, where gpu_shaders.py looks for them in an installed add-on. Caches
(__pycache__, *.pyc) are left out. Exits with a message, writing nothing, when the
compiled module is missing.
"""
import glob
import os
import sys
import zipfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ADDON = os.path.join(REPO, "addon", "airlight")
SHADERS = os.path.join(REPO, "shaders")


def package_files():
    """(path on disk, name in the zip) of every file the package holds."""
    files = []
    for root, dirs, names in os.walk(ADDON, followlinks=True):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(names):
            if name.endswith((".pyc", ".pyo")):
                continue
            path = os.path.join(root, name)
            files.append((path, os.path.join("airlight", os.path.relpath(path, ADDON))))
    for path in sorted(glob.glob(os.path.join(SHADERS, "*.glsl"))):
        files.append((path, os.path.join("airlight", "shaders", os.path.basename(path))))
    return files


def make_zip(out_path):
    """Writes the zip to _out_path_ and returns its member names. Raises FileNotFoundError
    when addon/airlight has no compiled _native module."""
    if not glob.glob(os.path.join(ADDON, "_native*.so")) and not glob.glob(os.path.join(ADDON, "_native*.pyd")):
        raise FileNotFoundError(f"no compiled _native module in {ADDON}: run `make build` first")
    files = package_files()
    os.makedirs(os.path.dirname(os.path.abspath(out_path)), exist_ok=True)
    tmp = out_path + ".tmp"
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        for path, arcname in files:
            zf.write(os.path.realpath(path), arcname)
    os.replace(tmp, out_path)
    return [arcname for _, arcname in files]


def main(argv):
    if len(argv) != 1:
        print("usage: package.py OUT.zip", file=sys.stderr)
        return 2
    try:
        names = make_zip(argv[0])
    except FileNotFoundError as e:
        print(f"package: {e}", file=sys.stderr)
        return 1
    print(f"add-on package: {argv[0]} ({len(names)} files)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
