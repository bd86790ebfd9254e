#!/usr/bin/env python3
"""Compares two drape databases of the same textile hold point by hold point (simulated rows only):
whether the stored rest shapes are byte-identical, the largest particle distance where they are not,
whether their silhouette views are byte-identical, and the simulation wall times. A database with members has
several rows per hold point: the k-th row (by id) of a hold point is compared with the other database's k-th, and
its key gets "#k" for k > 0. Usage: compare_builds.py REFERENCE.sqlite OTHER.sqlite > compare.csv"""
import sqlite3
import struct
import sys


def rows(path):
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    out, seen = {}, {}
    for sid, key, spacing, wall, blob in con.execute(
            "SELECT id, hold_key, spacing, wall_time_s, positions FROM simulations "
            "WHERE source = 'identity' AND status = 'done' ORDER BY id").fetchall():
        masks = b"".join(bytes(m) for (m,) in con.execute(
            "SELECT mask FROM views WHERE simulation_id = ? ORDER BY view_angle_deg", (sid,)))
        k = seen.get(key, 0)
        seen[key] = k + 1
        out[key if k == 0 else f"{key}#{k}"] = (spacing, wall, bytes(blob), masks)
    return out


def points(blob):
    """Positions blob v1 (docs/database.md, "Blobs"): "THPS", u16 version, u16 DOFs, u64 N, N x 3 doubles,
    u32 CRC. Returns the particles as (x, y, z) tuples."""
    assert blob[:4] == b"THPS", "not a positions blob"
    n = struct.unpack_from("<Q", blob, 8)[0]
    xyz = struct.unpack_from("<%dd" % (3 * n), blob, 16)
    return [xyz[3 * k:3 * k + 3] for k in range(n)]


a, b = rows(sys.argv[1]), rows(sys.argv[2])
print("hold_key,spacing_ref_m,spacing_other_m,identical_positions,identical_views,max_particle_distance_m,wall_ref_s,wall_other_s,wall_ratio_other_over_ref")
for key in sorted(set(a) & set(b)):
    sa, wa, pa, _ = a[key]
    sb, wb, pb, _ = b[key]
    same = pa == pb
    same_views = a[key][3] == b[key][3]
    diff = ""
    if not same and len(pa) == len(pb):
        diff = "%.6g" % max(sum((u - v) ** 2 for u, v in zip(p, q)) ** 0.5 for p, q in zip(points(pa), points(pb)))
    print(f"{key.replace(',', ' ')},{sa},{sb},{int(same)},{int(same_views)},{diff},{wa:.3f},{wb:.3f},{wb / wa:.4f}")
only = sorted(set(a) ^ set(b))
if only:
    print(f"# hold points in only one database: {len(only)}", file=sys.stderr)
