"""Writes the F table of the built native module (_native.special_F_table(), the data the
preview uploads in gpu_shaders.f_table_texture) as the harness's binary file:
int32 nu, int32 nT, float32 data[nu][nT] (little endian).

    /usr/bin/python3 benchmarks/gpu_preview/make_ftable.py OUT.bin [--native-dir DIR]
"""

import argparse
import os
import sys

import numpy as np


def main():
    p = argparse.ArgumentParser()
    p.add_argument("out")
    here = os.path.dirname(os.path.abspath(__file__))
    p.add_argument("--native-dir", default=os.path.join(here, "..", "..", "addon", "airlight"),
                   help="folder holding the built _native module")
    args = p.parse_args()
    sys.path.insert(0, os.path.abspath(args.native_dir))
    import _native  # noqa: E402  (the built extension)
    table = _native.special_F_table()
    data = np.ascontiguousarray(table["data"], dtype="<f4")
    if data.shape != (table["nu"], table["nT"]):
        raise SystemExit(f"unexpected F table shape {data.shape}")
    with open(args.out, "wb") as f:
        f.write(np.array(data.shape, dtype="<i4").tobytes())
        f.write(data.tobytes())
    print(f"{args.out}: F table {data.shape[0]} x {data.shape[1]} (k = {table['k']}), "
          f"from {_native.__file__}")


if __name__ == "__main__":
    main()
