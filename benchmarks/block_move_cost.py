"""What the region block moves cost per sweep, and what they move, in `adapt`.

For each knowledge file and new home given: `adapt` twice from the same knowledge and seed, with the
block moves off (``block_moves="off"``) and on (the default, ``"adapt"``), CPU time of each whole
`adapt` (``time.process_time``: the machine is shared, wall time is noisy), and, in the run with the
moves, the CPU time of the block passes themselves (:func:`spco.model.blocks.region_block_step`,
timed around each call) and how many blocks they moved. Prints per run the sweep's CPU time without
and with the moves, their ratio, and the block passes' share; then the median and range of the
ratio over runs.

    python benchmarks/block_move_cost.py --data …/sigverse --images …/sigverse_images \\
        --knowledge results/calibration/models/knowledge_colour-hog_4_0.spco --homes 2LDK_3,1LDK_3

Development homes only (benchmarks/SPLIT.md): the script refuses nothing itself; give it
development knowledge files and homes.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
import warnings
from pathlib import Path


def _load(data: Path, images: Path | None, name: str, features: str):
    from spco.data.loading import load_homes
    from spco.features import build_extractor

    if features == "fc7":
        return load_homes(data, names=[name], teaching_rate=0)[0]
    extractor = build_extractor(features)
    return load_homes(data, names=[name], teaching_rate=0, extractor=extractor, images=images)[0]


def measure(knowledge_file: Path, home, iterations: int, seed: int) -> dict:
    """CPU seconds of `adapt` without and with the moves; the block passes' seconds and moves."""
    import spco.knowledge as kn
    from spco.model import assignments, blocks

    knowledge = kn.load_knowledge(knowledge_file)
    off = dataclasses.replace(knowledge, hyperparameters=dataclasses.replace(knowledge.hyperparameters,
                                                                           block_moves="off"))
    on = dataclasses.replace(knowledge, hyperparameters=dataclasses.replace(knowledge.hyperparameters,
                                                                          block_moves="adapt"))
    kn.adapt(on, home, n_iterations=2, random_state=seed)  # compile and warm every path first
    start = time.process_time()
    kn.adapt(off, home, n_iterations=iterations, random_state=seed)
    seconds_off = time.process_time() - start
    spent = {"seconds": 0.0, "calls": 0, "moved": 0, "blocks": 0, "counting": 0.0}
    real = blocks.region_block_step

    def timed(homes, concepts, regions, *args):
        t0 = time.process_time()
        new = real(homes, concepts, regions, *args)
        t1 = time.process_time()
        spent["seconds"] += t1 - t0
        spent["calls"] += 1
        _, first = blocks.region_blocks(homes, concepts, regions, args[0].shape[1], args[4])
        spent["blocks"] += first.size
        spent["moved"] += int((new[first] != concepts[first]).sum())
        spent["counting"] += time.process_time() - t1  # this script's counting: not the sampler's
        return new

    assignments.region_block_step = timed
    try:
        start = time.process_time()
        kn.adapt(on, home, n_iterations=iterations, random_state=seed)
        seconds_on = time.process_time() - start - spent["counting"]
    finally:
        assignments.region_block_step = real
    return {"off": seconds_off / iterations, "on": seconds_on / iterations,
            "block": spent["seconds"] / max(spent["calls"], 1), "moved": spent["moved"],
            "blocks": spent["blocks"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--images", type=Path)
    parser.add_argument("--knowledge", type=Path, action="append", required=True)
    parser.add_argument("--homes", required=True, help="comma-separated new homes (development)")
    parser.add_argument("--features", default="colour-hog")
    parser.add_argument("--iterations", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    ratios = []
    print("| knowledge | home | CPU s/sweep off | on | ratio | block pass s (share of on) | blocks moved |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for k_file in args.knowledge:
        for name in args.homes.split(","):
            home = _load(args.data, args.images, name, args.features)
            r = measure(k_file, home, args.iterations, args.seed)
            ratios.append(r["on"] / r["off"])
            print(f"| {k_file.name} | {name} | {r['off']:.4f} | {r['on']:.4f} | {r['on'] / r['off']:.3f} | "
                  f"{r['block']:.5f} ({r['block'] / r['on']:.1%}) | {r['moved']} of {r['blocks']} |",
                  flush=True)
    print(f"ratio on/off: median {statistics.median(ratios):.3f}, range {min(ratios):.3f}–{max(ratios):.3f} "
          f"over {len(ratios)} runs; block pass alone: see the share column")



if __name__ == "__main__":
    main()
