#!/usr/bin/env python3
"""Score our outputs with the peer harness's own metric, beside the best peer.

    harness_ratios.py OUTDIR [--bench DIR] [--harness DIR] [--samples N]

OUTDIR holds `<shape>_<variant>.ply` as `evalall.sh` writes them. Each is
scored by the harness's `metrics.py` (its venv, 100k samples like the peer
run in best_peers.tsv) against the same ground truth, and compared with
the best peer of that input (best_peers.tsv, beside this script). Prints a
markdown table and the ratio's median and max per variant; writes
OUTDIR/harness.tsv.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def best_peers():
    rows = {}
    for line in open(os.path.join(HERE, "best_peers.tsv")):
        if line.startswith("#"):
            continue
        shape, variant, cd, cd_peer, f1, f1_peer = line.rstrip("\n").split("\t")
        rows[(shape, variant)] = (float(cd), cd_peer, float(f1), f1_peer)
    return rows


def ground_truth(args, shape):
    if shape == "fandisk":
        return os.path.join(args.shared, "data/fandisk/fandisk.off")
    return os.path.join(args.harness, "gt", shape + ".ply")


def score(args, mesh, gt):
    python = os.path.join(args.bench, ".venv/bin/python")
    out = subprocess.run(
        [python, os.path.join(args.bench, "metrics.py"), "--gt", gt, mesh, "--n", str(args.samples)],
        capture_output=True, text=True, check=True,
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("outdir")
    ap.add_argument("--bench", default=os.environ.get("BENCH", "/work/bench"))
    ap.add_argument("--harness", default=os.environ.get("HARNESS", "/work/runs/h11"))
    ap.add_argument("--shared", default=os.environ.get("SHARED", "../shared"))
    ap.add_argument("--samples", type=int, default=100000)
    args = ap.parse_args()
    peers = best_peers()
    ratios = {}
    print("| shape | variant | ours CD-L1 ‰ | best peer CD-L1 ‰ | ratio | ours F@1% | best peer F@1% | wt / cc / g |")
    print("|---|---|---|---|---|---|---|---|")
    with open(os.path.join(args.outdir, "harness.tsv"), "w") as tsv:
        for (shape, variant), (cd, cd_peer, f1, f1_peer) in sorted(peers.items()):
            mesh = os.path.join(args.outdir, f"{shape}_{variant}.ply")
            if not os.path.exists(mesh):
                continue
            m = score(args, mesh, ground_truth(args, shape))
            ours = 1000 * m["chamfer_l1_rel"]
            ratio = ours / cd
            ratios.setdefault(variant, []).append(ratio)
            topo = f"{'y' if m['is_watertight'] else 'n'} / {m['components']} / {m.get('genus')}"
            print(f"| {shape} | {variant} | {ours:.3f} | {cd:.3f} ({cd_peer}) | {ratio:.2f} | "
                  f"{m['fscore@1pct']:.3f} | {f1:.3f} ({f1_peer}) | {topo} |")
            tsv.write(f"{shape}\t{variant}\t{ours:.4f}\t{cd}\t{ratio:.4f}\t{m['fscore@1pct']:.4f}\t{f1}\t{topo}\n")
            sys.stdout.flush()
    print()
    for variant, r in sorted(ratios.items()):
        print(f"- {variant}: median {statistics.median(r):.2f}, max {max(r):.2f} ({len(r)} shapes)")


if __name__ == "__main__":
    main()
