#!/usr/bin/env python3
"""Projected LCD speed-up of a gather farm from bench_farm.sh's measurements
(docs/benchmarks.md, "Gather farm scaling").

Usage: farm_model.py WORK_DIR [--spp 40] [--budget 64] [--gbps 10] [--alpha-us 20]

Reads every g<G>r<rep>/metrics.jsonl in WORK_DIR (G > 0) and takes from them
  r        samples per CPU second of one gather rank (texels x spp / round CPU)
  m_ep     the master's CPU ms per epoch in its polls of the sum
  c_ep     the busiest gather rank's MPI-thread CPU ms per epoch
Model, for G gather ranks (one per core of the farm), an image of S bytes
(8 x cv_lcd_accum_words) and rounds of `spp` samples per texel:
  t_r      = texels x spp / r                     one round on one core
  L        = ceil(log2(G + 1))                    levels of the binomial sum
  T_ep     = 2 L (alpha + S / B) + L t_add        one epoch: L transfers up,
                                                  L adds at the tree's root,
                                                  L transfers down (bandwidth
                                                  B, latency alpha)
  T_key    = ceil(budget / G) t_r + T_ep + 0.1 s  a key's image complete: its
                                                  rounds, the last epoch, the
                                                  master's epoch period
  speed-up = T_key(1) / T_key(G)
t_add is the add of S bytes on one core; bench_farm measures what a gather
rank's MPI thread spends per epoch (c_ep), which bounds the root's L adds.
"""
import glob
import json
import math
import os
import re
import statistics
import sys


def main():
    args = sys.argv[1:]
    if not args or args[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if args else 1
    work = args[0]
    opt = {"--spp": 40.0, "--budget": 64.0, "--gbps": 10.0, "--alpha-us": 20.0}
    for i in range(1, len(args) - 1, 2):
        if args[i] not in opt:
            print(f"farm_model.py: unknown option {args[i]}", file=sys.stderr)
            return 1
        opt[args[i]] = float(args[i + 1])
    rates, m_ep, c_ep = [], [], []
    for path in sorted(glob.glob(os.path.join(work, "g*r*", "metrics.jsonl"))):
        g = int(re.search(r"g(\d+)r\d+", path).group(1))
        lines = [json.loads(l) for l in open(path) if '"summary"' in l]
        if g == 0 or not lines or "lcd_allreduce" not in lines[-1]:
            continue
        a = lines[-1]["lcd_allreduce"]
        if a["gather_rounds"] > 0 and a["gather_round_cpu_ms"] > 0:
            rates.append(a["gather_round_cpu_ms"])
        if a["data_epochs"] > 0:
            m_ep.append(a["poll_cpu_ms"] / a["data_epochs"])
        if a["epochs"] > 0 and "gather_comm_cpu_ms_max" in a:
            c_ep.append(a["gather_comm_cpu_ms_max"] / a["epochs"])
    if not rates:
        print(f"farm_model.py: {work}: no gather-rank figures (run bench_farm.sh first)", file=sys.stderr)
        return 1
    # bench_farm.sh's LCD size and spp are in its header line; the defaults:
    w, h, spp_bench = 400, 300, 4
    hdr = os.path.join(work, "bench.txt")
    if os.path.exists(hdr):
        m = re.search(r"LCD (\d+)x(\d+) x (\d+) spp", open(hdr).read())
        if m:
            w, h, spp_bench = (int(v) for v in m.groups())
    r = statistics.median(w * h * spp_bench / (ms * 1e-3) for ms in rates)
    S = 8 * (16 + 5 * w * h)
    B = opt["--gbps"] * 1e9 / 8
    alpha = opt["--alpha-us"] * 1e-6
    t_add = min(c_ep) * 1e-3 if c_ep else 0.0  # pessimistic: a whole epoch's MPI-thread CPU
    t_r = w * h * opt["--spp"] / r
    budget = int(opt["--budget"])

    def t_key(g):
        L = math.ceil(math.log2(g + 1))
        t_ep = 2 * L * (alpha + S / B) + L * t_add
        return math.ceil(budget / g) * t_r + t_ep + 0.1, t_ep

    base = t_key(1)[0]
    print(f"inputs: r = {r / 1e6:.2f} M samples per CPU second of a gather rank (median of {len(rates)} runs); "
          f"image {w} x {h} = {S / 1e6:.2f} MB; round of {opt['--spp']:.0f} spp t_r = {t_r:.2f} s; "
          f"budget {budget} rounds; B = {opt['--gbps']:.0f} Gb/s, alpha = {opt['--alpha-us']:.0f} us; "
          f"t_add <= {t_add * 1e3:.2f} ms (a gather rank's MPI-thread CPU per epoch, smallest run); "
          f"master per epoch {statistics.median(m_ep) if m_ep else float('nan'):.2f} ms CPU (median)")
    print("| gather cores G | levels L | epoch T_ep s | rounds per rank | key complete T_key s | speed-up |")
    print("|---|---|---|---|---|---|")
    for g in (1, 2, 4, 8, 16, 32, 64, 128):
        tk, tep = t_key(g)
        print(f"| {g} | {math.ceil(math.log2(g + 1))} | {tep:.3f} | {math.ceil(budget / g)} | {tk:.2f} | {base / tk:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
