#!/usr/bin/env python3
"""Block comparison: dvs's transformer output(s) and torch's bf16 output against torch's fp32 reference.

  compare_block.py BLOCK_DIR [--json FILE]

Reads BLOCK_DIR/out_torch_fp32.npy (reference), out_torch_bf16.npy and every out_dvs_<family>.npy (written by
dvs-bench --filter gpu), prints the relative L2 error ||x - ref|| / ||ref|| of each, and appends one JSON line
per output to FILE. Goal (issue 21): dvs's error <= 2x torch-bf16's error against the fp32 reference.
numpy only.
"""
import argparse
import glob
import json
import os

import numpy as np


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--json", default="")
    a = ap.parse_args()
    out = open(a.json, "a") if a.json else None

    def emit(d):
        d = dict(source="compare", case="block_error", **d)
        print(json.dumps(d), flush=True)
        if out:
            out.write(json.dumps(d) + "\n")
            out.flush()

    ref_path = os.path.join(a.dir, "out_torch_fp32.npy")
    if not os.path.exists(ref_path):
        emit(dict(skipped="no %s (torch_ref.py did not write the block)" % ref_path))
        return 0
    ref = np.load(ref_path).astype(np.float64)
    norm = np.linalg.norm(ref)
    errs = {}
    paths = [os.path.join(a.dir, "out_torch_bf16.npy")] + sorted(glob.glob(os.path.join(a.dir, "out_dvs_*.npy")))
    for p in paths:
        if not os.path.exists(p):
            continue
        impl = os.path.basename(p)[4:-4]  # torch_bf16, dvs_<family>
        x = np.load(p).astype(np.float64)
        if x.shape != ref.shape:
            emit(dict(impl=impl, error="shape %s vs reference %s" % (list(x.shape), list(ref.shape))))
            continue
        finite = bool(np.isfinite(x).all())
        e = float(np.linalg.norm(x - ref) / norm) if finite else float("inf")
        errs[impl] = e
        d = dict(impl=impl, rel_l2_vs_fp32=e, max_abs=float(np.abs(x - ref).max()) if finite else None,
                 finite=finite)
        tb = errs.get("torch_bf16")
        if impl.startswith("dvs_") and tb:
            d["ratio_to_torch_bf16_error"] = e / tb
            d["goal"] = "<= 2x torch bf16's error"
            d["pass"] = bool(e <= 2 * tb)
        emit(d)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
