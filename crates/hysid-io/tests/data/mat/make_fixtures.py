"""Writes the MAT-file fixtures of tests/mat_files.rs and their CSV twins.

Not run by CI (it needs numpy and scipy: `pip install numpy scipy`); the
files it writes are committed. Run from this folder: `python3 make_fixtures.py`.

- scipy_*.mat: written by scipy.io.savemat (level 5), compressed or not,
  row or column vectors, float64 / float32 / int16 signals `u` and `y`;
- matlab_header.mat: a scipy file whose 128-byte header is rewritten as
  MATLAB writes it: the text `MATLAB 5.0 MAT-file, Platform: PCWIN64,
  Created on: ...` padded with spaces, the subsystem data offset as 8
  spaces (the format's "no subsystem data"), version 0x0100, `IM`;
- level4.mat: scipy's level-4 format;
- v73_header.mat: the first 520 bytes of an HDF5-based MAT-file (`save
  -v7.3`): MATLAB's 512-byte user block with its header text, then the
  HDF5 signature; enough to be recognised, not a readable HDF5 file.
Every .mat has a .csv twin with the same signals (values exact: the CSV
holds the float64 value of each sample, printed with repr).
"""
import numpy as np
import scipy.io as sio

rng = np.random.default_rng(1)
n = 200
u = rng.uniform(-1, 1, n)
y = np.zeros(n)
for k in range(1, n):
    y[k] = 0.5 * y[k - 1] + u[k - 1]


def twin(name, uu, yy):
    with open(name + ".csv", "w") as f:
        f.write("u,y\n")
        for a, b in zip(uu, yy):
            f.write(f"{float(a)!r},{float(b)!r}\n")


cases = [
    ("scipy_f64_col_compressed", dict(do_compression=True, oned_as="column"), np.float64, 1),
    ("scipy_f64_row", dict(do_compression=False, oned_as="row"), np.float64, 1),
    ("scipy_f32_col", dict(do_compression=False, oned_as="column"), np.float32, 1),
    ("scipy_i16_row_compressed", dict(do_compression=True, oned_as="row"), np.int16, 1000),
]
for name, kw, dtype, scale in cases:
    uu = (u * scale).astype(dtype)
    yy = (y * scale).astype(dtype)
    sio.savemat(name + ".mat", {"u": uu, "y": yy}, **kw)
    twin(name, uu, yy)

sio.savemat("matlab_header.mat", {"u": u, "y": y}, do_compression=True, oned_as="column")
data = bytearray(open("matlab_header.mat", "rb").read())
text = b"MATLAB 5.0 MAT-file, Platform: PCWIN64, Created on: Mon Nov 23 10:00:00 2026"
data[:116] = text.ljust(116, b" ")
data[116:124] = b" " * 8  # subsystem data offset: none
data[124:126] = b"\x00\x01"  # version 0x0100, little-endian
data[126:128] = b"IM"
open("matlab_header.mat", "wb").write(bytes(data))
twin("matlab_header", u, y)

sio.savemat("level4.mat", {"u": u, "y": y}, format="4")

header = b"MATLAB 7.3 MAT-file, Platform: PCWIN64, Created on: Mon Nov 23 10:00:00 2026 HDF5 schema 1.00 ."
block = bytearray(header.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM")
block += b"\x00" * (512 - len(block))
block += b"\x89HDF\r\n\x1a\n"
open("v73_header.mat", "wb").write(bytes(block))
