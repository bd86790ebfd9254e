#!/usr/bin/env python3
"""Usage: shapes_digest.py DB.sqlite ... — per database an MD5 digest of every simulation row's rest_reached flag and
stored positions, in row order: equal digests mean the builds stored the same rest shapes bit for bit."""
import hashlib
import sqlite3
import sys

for path in sys.argv[1:]:
    h = hashlib.md5()
    for row in sqlite3.connect(path).execute("select rest_reached, positions from simulations order by id"):
        for v in row:
            h.update(v if isinstance(v, bytes) else str(v).encode())
    print(f"{path} {h.hexdigest()}")
