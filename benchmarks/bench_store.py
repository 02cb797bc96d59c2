"""What verifying the result store costs: 1000 campaign-like chunk results written and read
back through :class:`~optimizers.common.store.ResultStore` (envelope, checksum, key and store
checks, a schema) against the same bytes written and read without any of it (atomic write and
decode only, as a store without verification does), timed in the same run.

    python benchmarks/bench_store.py [--n 1000] [--fmt json] [--json FILE]

A chunk result is a dict of 10 lists of 100 floats (a campaign task's per-case outcomes). The
target: the verification adds < 2 % of a 1000-case planar campaign's wall time (~10 min), i.e.
well under 12 s for its store traffic; printed as the absolute cost per 1000 results and as a
share of 600 s. Writes fsync each file, so their time depends on the disk; the reads, and the
difference between the two columns, are what the verification adds.
"""

from __future__ import annotations

import argparse
import json
import pickle
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from optimizers.common.checkpoint import atomic_write_bytes  # noqa: E402
from optimizers.common.executor import TaskKey  # noqa: E402
from optimizers.common.store import ResultSchema, ResultStore  # noqa: E402

FIELDS = ("success", "touchdown_speed_m_s", "miss_distance_m", "fuel_kg", "time_s",
          "propellant_left_kg", "downrange_offset_m", "crossrange_offset_m", "thrust_scale",
          "isp_scale")
CHUNK = 100
CAMPAIGN_S = 600.0


def chunk_result(k: int, rng: np.random.Generator, fmt: str) -> dict:
    value = {"case": list(range(CHUNK * k, CHUNK * (k + 1)))}
    value.update({f: rng.normal(size=CHUNK).tolist() for f in FIELDS[:9]})
    if fmt == "npz":
        return {f: np.asarray(v) for f, v in value.items()}
    return value


def _expected(key: TaskKey) -> dict:
    return {"case": list(range(CHUNK * key.index, CHUNK * (key.index + 1)))}


def _plain_bytes(value, fmt: str) -> bytes:
    if fmt == "json":
        return json.dumps(value).encode()
    if fmt == "pickle":
        return pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    import io

    buf = io.BytesIO()
    np.savez_compressed(buf, **value)
    return buf.getvalue()


def _plain_read(path: Path, fmt: str):
    raw = path.read_bytes()
    if fmt == "json":
        return json.loads(raw)
    if fmt == "pickle":
        return pickle.loads(raw)
    import io

    with np.load(io.BytesIO(raw), allow_pickle=False) as z:
        return {f: z[f] for f in z.files}


def run(n: int, fmt: str) -> dict:
    rng = np.random.default_rng(0)
    values = [chunk_result(k, rng, fmt) for k in range(n)]
    keys = [TaskKey("fly@x1", 0, k) for k in range(n)]
    schema = ResultSchema(required=("case", *FIELDS[:9]), same_length=("case", *FIELDS[:9]),
                          expected=_expected)
    out = {}
    with tempfile.TemporaryDirectory(prefix="bench_store_") as d:
        store = ResultStore(Path(d) / "verified", {"bench": "store"}, fmt=fmt, schema=schema)
        plain_dir = Path(d) / "plain"
        plain_dir.mkdir()
        ext = {"json": ".json", "pickle": ".pkl", "npz": ".npz"}[fmt]
        # alternate the two in blocks of 50, so both meet the same conditions
        t = {"plain_write": 0.0, "verified_write": 0.0, "plain_read": 0.0, "verified_read": 0.0,
             "encode_plain": 0.0, "encode_verified": 0.0}
        for lo in range(0, n, 50):
            block = range(lo, min(lo + 50, n))
            t0 = time.perf_counter()
            for k in block:
                atomic_write_bytes(plain_dir / (keys[k].filename + ext),
                                   _plain_bytes(values[k], fmt))
            t1 = time.perf_counter()
            for k in block:
                store.put(keys[k], values[k])
            t2 = time.perf_counter()
            t["plain_write"] += t1 - t0
            t["verified_write"] += t2 - t1
        for lo in range(0, n, 50):
            block = range(lo, min(lo + 50, n))
            t0 = time.perf_counter()
            for k in block:
                _plain_read(plain_dir / (keys[k].filename + ext), fmt)
            t1 = time.perf_counter()
            for k in block:
                store.load(keys[k])
            t2 = time.perf_counter()
            t["plain_read"] += t1 - t0
            t["verified_read"] += t2 - t1
        # the in-memory part alone (no disk): what the envelope itself costs
        t0 = time.perf_counter()
        for k in range(n):
            _plain_bytes(values[k], fmt)
        t1 = time.perf_counter()
        for k in range(n):
            store.encode(keys[k], values[k])
        t2 = time.perf_counter()
        t["encode_plain"], t["encode_verified"] = t1 - t0, t2 - t1
    extra = (t["verified_write"] - t["plain_write"]) + (t["verified_read"] - t["plain_read"])
    out.update(fmt=fmt, n=n, **{k + "_s": v for k, v in t.items()}, verification_s=extra,
               share_of_campaign_pct=100.0 * extra * (1000 / n) / CAMPAIGN_S)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=1000, help="chunk results (default 1000)")
    ap.add_argument("--fmt", nargs="*", default=["json", "npz", "pickle"])
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    rows = [run(args.n, f) for f in args.fmt]
    print(f"{args.n} chunk results (10 lists of {CHUNK} floats); seconds for all of them")
    print("| format | write plain | write verified | read plain | read verified | "
          "encode plain | encode verified | verification | of a 600 s campaign |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['fmt']} | {r['plain_write_s']:.3f} | {r['verified_write_s']:.3f} | "
              f"{r['plain_read_s']:.3f} | {r['verified_read_s']:.3f} | "
              f"{r['encode_plain_s']:.3f} | {r['encode_verified_s']:.3f} | "
              f"{r['verification_s']:+.3f} | {r['share_of_campaign_pct']:+.3f} % |")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
