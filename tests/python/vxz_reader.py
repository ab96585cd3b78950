"""o_voxel's `.vxz` container read back from its description in docs/FORMAT.md (TRELLIS.2's
dual grid dataset), the way `o-voxel/o_voxel/io/vxz.py` `read_vxz` of microsoft/TRELLIS.2 reads
it: voxels by chunk, each chunk's octree of Morton codes, the attribute rows in that order."""

import json
import struct

import numpy as np
import zstandard


def unmorton(code):
    """(x, y, z) of a Morton code whose bit 3b+2 is x's bit b, 3b+1 y's, 3b z's."""
    xyz = [0, 0, 0]
    for b in range(10):
        for axis in range(3):
            xyz[axis] |= (code >> (3 * b + 2 - axis) & 1) << b
    return xyz


def octree_codes(data, depth):
    """Morton codes of an octree stored as occupancy bytes in depth-first pre-order."""
    codes, pos = [], 0

    def walk(prefix, level):
        nonlocal pos
        mask = data[pos]
        pos += 1
        for child in range(8):
            if mask >> child & 1:
                code = prefix << 3 | child
                if level + 1 == depth:
                    codes.append(code)
                else:
                    walk(code, level + 1)

    walk(0, 0)
    assert pos == len(data), "octree bytes left over"
    return codes


def read_vxz(path):
    """Voxels int [N, 3], attributes {name: uint8 [N, channels]} and the JSON header."""
    data = path.read_bytes()
    assert data[:3] == b"VXZ" and data[3] == 0
    start = struct.unpack(">I", data[4:8])[0]
    header = json.loads(data[8:start])
    blob = data[start:]
    for key in ("chunk_size", "filter", "compression", "compression_level", "attr_interleave",
                "attr", "chunks"):
        assert key in header, key
    assert header["filter"] == "none" and header["attr_interleave"] == "as_is"
    assert header["compression"] == "zstd"
    size = header["chunk_size"]
    depth = size.bit_length() - 1
    attrs = sorted(header["attr"])  # read back in sorted order; rows follow the voxels
    coords, rows = [], {name: [] for name, _ in attrs}
    for chunk in header["chunks"]:
        assert set(chunk) == {"idx", "ptr", "svo"} | set(rows)
        off, length = chunk["ptr"]
        part = blob[off:off + length]

        def stream(key):
            o, n = chunk[key]
            # python-zstandard's one-shot decompress needs the size in the frame header.
            return zstandard.ZstdDecompressor().decompress(part[o:o + n])

        codes = octree_codes(stream("svo"), depth)
        assert codes == sorted(set(codes))
        coords += [[c * size + u for c, u in zip(chunk["idx"], unmorton(k))] for k in codes]
        for name, channels in attrs:
            raw = np.frombuffer(stream(name), np.uint8)
            assert len(raw) == len(codes) * channels
            rows[name].append(raw.reshape(-1, channels))
    assert len(coords) == header["num_voxel"]
    return (np.array(coords, np.int64),
            {k: np.concatenate(v) for k, v in rows.items()}, header)
