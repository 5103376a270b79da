"""Minimal .npy reading and writing for the preview test (python3 without numpy): u8 and little-endian f32,
C order, as flat lists with their shape."""
import ast
import struct


def read_npy(path):
    with open(path, "rb") as f:
        data = f.read()
    if data[:6] != b"\x93NUMPY":
        raise SystemExit(f"{path}: not an .npy file")
    if data[6] == 1:
        (hlen,) = struct.unpack("<H", data[8:10])
        start = 10
    else:
        (hlen,) = struct.unpack("<I", data[8:12])
        start = 12
    header = ast.literal_eval(data[start:start + hlen].decode("latin1"))
    if header["fortran_order"]:
        raise SystemExit(f"{path}: Fortran order is not supported")
    shape = tuple(header["shape"])
    count = 1
    for d in shape:
        count *= d
    body = data[start + hlen:]
    descr = header["descr"]
    if descr in ("|u1", "<u1"):
        values = list(body[:count])
    elif descr == "<f4":
        values = list(struct.unpack(f"<{count}f", body[:4 * count]))
    else:
        raise SystemExit(f"{path}: dtype {descr} is not supported")
    return shape, values


def write_npy(path, shape, values, dtype):
    descr = "|u1" if dtype == "u1" else "<f4"
    dims = ", ".join(str(d) for d in shape) + ("," if len(shape) == 1 else "")
    header = "{'descr': '%s', 'fortran_order': False, 'shape': (%s), }" % (descr, dims)
    pad = (64 - (10 + len(header) + 1) % 64) % 64
    header = header + " " * pad + "\n"
    with open(path, "wb") as f:
        f.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode("latin1"))
        f.write(bytes(values) if dtype == "u1" else struct.pack(f"<{len(values)}f", *values))
