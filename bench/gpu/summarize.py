#!/usr/bin/env python3
"""Table of the device stage: each case, dvs per kernel family, torch, the ratio and the issue's goals.

  summarize.py TORCH_JSONL DVS_JSONL [> summary.md]

Joins torch_ref.py's lines and dvs-bench --filter gpu's (plus compare_block.py's) by case and shape. The ratio
uses dvs's fastest family whose sampled check passed; goals from issue 21 (first light / tuned). A dvs row
whose check failed shows FAIL instead of a rate and never counts.
"""
import json
import sys

# case -> (torch backend to compare with, first-light goal, tuned goal, higher_is_better)
GOALS = {
    "gemm": ("bfloat16", 0.4, 0.65, True),
    "attention": ("sdpa_flash", 0.35, 0.7, True),
    "conv3d": ("bfloat16", 0.3, 0.6, True),
    "copy": ("copy_ (D2D)", 0.7, 0.85, True),
    "block": ("plain torch eager (SDPA)", 4.0, 2.0, False),  # time ratio dvs / torch
}


def load(path):
    rows = []
    try:
        for line in open(path):
            line = line.strip()
            if line.startswith("{"):
                try:
                    rows.append(json.loads(line))
                except ValueError:
                    pass
    except OSError:
        pass
    return rows


def rate(r):
    # A figure of 0.0 (a slow CPU run rounds its TFLOP/s to zero) is a rate, not a missing one.
    return r["tflops"] if r.get("tflops") is not None else r.get("gbps")


def torch_row(rows, case, shape, want):
    cands = [r for r in rows if r.get("case") == case and r.get("shape") == shape and "error" not in r]
    for r in cands:
        if want in (r.get("backend", ""), r.get("dtype", "")) or r.get("backend", "") == want:
            return r
    pref = [r for r in cands if r.get("dtype") == "bfloat16"] or cands
    return pref[0] if pref else None


def main():
    torch_rows, dvs_rows = load(sys.argv[1]), load(sys.argv[2]) if len(sys.argv) > 2 else []
    # The sweep's lines (stage_bench.sh step 4) carry "variant": a table of their own, after the main one.
    sweep_rows = [r for r in dvs_rows if "variant" in r]
    dvs_rows = [r for r in dvs_rows if "variant" not in r]
    out = []
    info = [r for r in dvs_rows if r.get("case") == "dvs_info"] + [r for r in torch_rows if r.get("case") == "torch_info"]
    for r in info:
        out.append("- " + ", ".join("%s: %s" % (k, v) for k, v in r.items() if k not in ("case", "source")))
    ceil = [r for r in torch_rows if r.get("case") == "ceiling_matmul" and "tflops" in r]
    for r in ceil:
        out.append("- torch ceiling %s %s: %.1f TFLOP/s" % (r["shape"], r.get("dtype"), r["tflops"]))
    for r in dvs_rows:
        if r.get("case") == "mma_rate":
            out.append("- dvs coopmat MMA rate: " + ("%.1f TFLOP/s" % r["tflops"] if "tflops" in r else r.get("skipped", "?")))
    out.append("")
    families = []
    for r in dvs_rows:
        f = r.get("family")
        # copy's rows (transfer, shader) share the first column: the kernel families are the columns
        if f and f != "-" and f not in families and r.get("case") in GOALS and r.get("case") != "copy" and "error" not in r:
            families.append(f)
    head = ["case", "shape"] + ["dvs %s" % f for f in families] + ["torch", "ratio", "first light", "tuned"]
    out.append("| " + " | ".join(head) + " |")
    out.append("|" + "---|" * len(head))
    shapes = []
    for r in dvs_rows + torch_rows:
        k = (r.get("case"), r.get("shape"))
        if k[0] in GOALS and k[1] and k not in shapes:
            shapes.append(k)
    for case, shape in shapes:
        want, g1, g2, higher = GOALS[case]
        cells, best, best_f = [case, shape], None, ""
        mine = [r for r in dvs_rows if r.get("case") == case and r.get("shape") == shape]
        other = not any(r.get("family") in families for r in mine)  # copy: its rows in the first column
        for i, f in enumerate(families):
            rs = [r for r in mine if r.get("family") == f or (other and i == 0)]
            if not rs:
                cells.append("")
                continue
            r = rs[-1]
            if other and case != "block":  # the fastest passing row, named (transfer or shader copy)
                ok_rows = [x for x in rs if "error" not in x and x.get("check") != "FAIL" and rate(x) is not None]
                if ok_rows:
                    r = max(ok_rows, key=rate)
                    cells.append("%.4g" % rate(r) + (" GB/s" if "gbps" in r else "") +
                                 (" (%s)" % r["family"] if r.get("family") not in (None, "-") else ""))
                    if best is None or rate(r) > best:
                        best, best_f = rate(r), ""
                    continue
            if "error" in r:
                cells.append("error")
            elif r.get("check") == "FAIL":
                cells.append("FAIL (err %.1e)" % (r.get("rel_err") or float("inf")))
            elif case == "block":
                cells.append("%.1f ms (wall %.1f)" % (r["ms"], r.get("ms_wall", 0)))
                if best is None or r["ms"] < best:
                    best, best_f = r["ms"], f
            else:
                cells.append("%.4g" % rate(r) + (" GB/s" if "gbps" in r else ""))
                if best is None or rate(r) > best:
                    best, best_f = rate(r), f
        t = torch_row(torch_rows, case, shape, want)
        if t is None:
            cells += ["", "", "", ""]
        else:
            tv = t["ms"] if case == "block" else rate(t)
            cells.append(("%.1f ms" % tv) if case == "block" else ("%.4g" % tv + (" GB/s" if "gbps" in t else "")))
            if best is None or not tv:
                cells += ["", "miss", "miss"]
            else:
                ratio = best / tv
                cells.append("%.2fx (%s)" % (ratio, best_f) if best_f and len(families) > 1 else "%.2fx" % ratio)
                ok = (lambda g: ratio >= g) if higher else (lambda g: ratio <= g)
                cells += ["%s (%s%g)" % ("pass" if ok(g1) else "miss", ">=" if higher else "<=", g1),
                          "%s (%s%g)" % ("pass" if ok(g2) else "miss", ">=" if higher else "<=", g2)]
        out.append("| " + " | ".join(cells) + " |")
    errs = [r for r in dvs_rows if r.get("case") == "block_error" and "rel_l2_vs_fp32" in r]
    if not errs:  # compare_block.py did not run: torch's own line
        errs = [r for r in torch_rows if r.get("case") == "block_error" and "rel_l2_vs_fp32" in r]
    if errs:
        out.append("")
        out.append("Block error vs the fp32 torch reference (goal: dvs <= 2x torch bf16's):")
        for r in errs:
            extra = ""
            if "ratio_to_torch_bf16_error" in r:
                extra = "  (%.2fx torch bf16's: %s)" % (r["ratio_to_torch_bf16_error"], "pass" if r.get("pass") else "miss")
            out.append("- %s: %.3e%s" % (r.get("impl"), r["rel_l2_vs_fp32"], extra))
    sweep = [r for r in sweep_rows if r.get("source") != "stage" and r.get("case") in GOALS and r.get("case") != "block"]
    skipped = [r for r in sweep_rows if r.get("source") == "stage" and "skipped" in r]
    if sweep or skipped:
        out.append("")
        out.append("Sweep (DVS_TUNING variants, one case and family each; ratio to the torch figure of the main table):")
        out.append("| case | shape | family | variant | dvs | torch | ratio | kernels |")
        out.append("|---|---|---|---|---|---|---|---|")
        for r in sweep:
            case, shape = r.get("case"), r.get("shape")
            if "error" in r:
                cell, ratio = "error: %s" % r["error"][:80], ""
            elif r.get("check") == "FAIL" and "linear_coopmat_ablation" in r["variant"] and rate(r) is not None:
                # an ablation computes wrong results by design: its time is the figure
                cell, ratio = "%.4g (%.4g ms; ablated, wrong by design)" % (rate(r), r.get("ms", 0)), ""
            elif r.get("check") == "FAIL":
                cell, ratio = "FAIL (err %.1e)" % (r.get("rel_err") or float("inf")), ""
            elif rate(r) is None:
                cell, ratio = r.get("skipped", "no figure"), ""
            else:
                cell, ratio = "%.4g" % rate(r) + (" GB/s" if "gbps" in r else ""), ""
            t = torch_row(torch_rows, case, shape, GOALS[case][0])
            tv = rate(t) if t is not None else None
            if tv and "error" not in r and r.get("check") != "FAIL" and rate(r) is not None:
                ratio = "%.2fx" % (rate(r) / tv)
            out.append("| %s | %s | %s | %s | %s | %s | %s | %s |" % (case, shape, r.get("family"), r["variant"], cell,
                                                                  "%.4g" % tv if tv else "", ratio, r.get("shaders", "")))
        for r in skipped:
            out.append("- %s %s: skipped (%s)" % (r.get("case"), r.get("variant"), r["skipped"]))
    stats = [r for r in dvs_rows if r.get("case") == "pipeline_stats"]
    if stats:
        out.append("")
        out.append("Kernels' compiled-code statistics (VK_KHR_pipeline_executable_properties):")
        for r in stats:
            if "skipped" in r:
                out.append("- none: %s" % r["skipped"])
            else:
                out.append("- %s: %s" % (r.get("shader"), ", ".join("%s %s" % (k, v) for k, v in r.get("stats", {}).items())))
    split = [r for r in dvs_rows if len(r.get("shader_ms") or {}) > 1 and "variant" not in r]
    if split:
        out.append("")
        out.append("Time per shader (GPU ms per run, mean of the timed runs, largest first) where a case runs more than one:")
        for r in split:
            out.append("- %s %s %s: %s" % (r.get("case"), r.get("shape"), r.get("family"),
                                           ", ".join("%s %.3f" % (k, v) for k, v in sorted(r["shader_ms"].items(), key=lambda kv: -kv[1]))))
    fails = [r for r in dvs_rows if r.get("check") == "FAIL" or "error" in r]
    if fails:
        out.append("")
        out.append("Failures (wrong results or errors, not timings):")
        for r in fails:
            out.append("- %s %s %s: %s" % (r.get("case"), r.get("shape"), r.get("family"),
                                           r.get("error") or "rel_err %s > %s" % (r.get("rel_err"), r.get("tolerance"))))
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
