"""Samples without a view: camera drop-outs in the new homes, and a robot without a camera.

``dropout``
    The paper's general experiment (``spco experiment general``, 16 experienced homes, new homes
    1LDK_9, 2LDK_9, 3LDK_9, model ``spcotransfer+mi``) with 0, 30, 70 and 100 % of the new homes'
    views removed at random in each run (``--views-missing``; drawn from the trial's seed, train and
    test samples alike: a test sample without a view is named from its pose alone). Prints, per
    level, A_n and A_p: mean and 95 % interval of the mean over runs (new homes × trials).
``cc4f``
    The CC4F_turtlebot2 recording (a real robot without a camera: no visual file, every view
    missing) learnt on its own as ``spco fit`` and ``spco adapt`` learn it (``fit_knowledge`` on the
    home, then ``adapt`` to it; ``--prior paper`` for the paper's constants), then ``where`` for
    each of its names that was said: a drawn position
    is right when its nearest recorded sample belongs to a place of that name (``answers.json``,
    realigned as in ``benchmarks/japanese.py``). A_p per seed and its mean; ``--map`` also draws
    the home on the floor's ROS map (``map.yaml``).

    python benchmarks/missing_views.py dropout --data ../shared/datasets/sigverse \\
        --regions ../shared/datasets/sigverse_regions.json --trials 10 --out /tmp/dropout
    python benchmarks/missing_views.py cc4f --data ../shared/datasets/cc4f_turtlebot2 --seeds 5 \\
        --map /tmp/cc4f_map.png
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from japanese import cc4f_answers, mean_interval

LEVELS = (0.0, 30.0, 70.0, 100.0)


def run_dropout(args: argparse.Namespace) -> None:
    """The general experiment at each level of missing views."""
    from spco.evaluation.experiments import (
        PAPER_EXPERIENCED_HOMES,
        PAPER_NEW_HOMES,
        ExperimentConfig,
        run_experiment,
    )

    rows = []
    for level in args.levels:
        config = ExperimentConfig(experiment="general", settings=(16,), data=args.data, regions=args.regions,
                                  trials=args.trials, models=("spcotransfer+mi",), iterations=args.iterations,
                                  seed=args.seed, jobs=args.jobs, experienced_homes=PAPER_EXPERIENCED_HOMES,
                                  new_homes=PAPER_NEW_HOMES, views_missing=level)
        start = time.perf_counter()
        out = Path(args.out) / f"missing_{level:g}"
        result = run_experiment(config, out, resume=out.exists() and not args.force, force=args.force)
        runs = [r for r in result.results["runs"] if r["place"] == "mean"]
        a_n = np.array([r["name_accuracy"] for r in runs], dtype=float)
        a_p = np.array([r["position_accuracy"] for r in runs], dtype=float)
        rows.append((level, a_n, a_p, time.perf_counter() - start))
        print(f"{level:g} %: A_n {mean_interval(a_n)}, A_p {mean_interval(a_p)} ({a_n.size} runs)",
              flush=True)
    print("\n| views removed | runs | A_n | A_p | A_n − full | A_p − full |")
    print("|---:|---:|---:|---:|---:|---:|")
    full = next(((n.mean(), p.mean()) for lv, n, p, _ in rows if lv == 0), (math.nan, math.nan))
    for level, a_n, a_p, _ in rows:
        print(f"| {level:g} % | {a_n.size} | {mean_interval(a_n)} | {mean_interval(a_p)} "
              f"| {a_n.mean() - full[0]:+.3f} | {a_p.mean() - full[1]:+.3f} |")
    print("(mean ± half-width of the 95 % interval of the mean over new homes × trials)")


def run_cc4f(args: argparse.Namespace) -> None:
    """CC4F learnt on its own; A_p by nearest sample's place."""
    from spco.data.environment import Corpus
    from spco.data.loading import load_home
    from spco.knowledge import adapt, fit_knowledge, where
    from spco.model.hyperparameters import TransferHyperparameters
    from spco.model.prediction import UnknownNameError

    folder = Path(args.data)
    places, names = cc4f_answers(folder)
    home = load_home(folder)
    said = {w for s in home.sentences if s for w in s.split()}
    asked = sorted(n for n in set().union(*names) if n in said)
    xy = home.positions[:, :2]
    hyper = None
    if args.concepts or args.regions or args.kappa0:
        defaults = TransferHyperparameters()
        hyper = TransferHyperparameters(n_concepts=args.concepts or defaults.n_concepts,
                                        n_regions=args.regions or defaults.n_regions,
                                        kappa0=args.kappa0 or defaults.kappa0)
    print(f"CC4F: {home.n_samples} samples, {home.n_views} with a view, {len(asked)} names asked; "
          f"hyperparameters: {f'the defaults, prior {args.prior}' if hyper is None else hyper}", flush=True)
    scores = []
    last = None
    for seed in range(args.seeds):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the home is, by construction, the knowledge's own
            knowledge = fit_knowledge(Corpus([home]), n_iterations=args.iterations, random_state=seed,
                                      hyperparameters=hyper, prior=args.prior)
            model = adapt(knowledge, home, n_iterations=args.adapt_iterations, random_state=seed)
        per_name = {}
        for name in asked:
            try:
                drawn = where(model, name, n=10, random_state=seed).samples[:, :2]
            except UnknownNameError:
                per_name[name] = 0.0
                continue
            nearest = np.argmin(((drawn[:, None, :] - xy[None, :, :]) ** 2).sum(-1), axis=1)
            per_name[name] = float(np.mean([name in names[places[i]] for i in nearest]))
        scores.append(float(np.mean(list(per_name.values()))))
        wrong = {n: round(v, 1) for n, v in per_name.items() if v < 1}
        print(f"seed {seed}: A_p {scores[-1]:.3f}; below 1: {wrong}", flush=True)
        last = model
    print(f"\nA_p over {args.seeds} seeds: {mean_interval(np.array(scores))} (min {min(scores):.3f})")
    if args.map and last is not None:
        from spco.plots import plot_home_map

        image, extent = _ros_map(folder / "map.yaml")
        predictions = {}
        for name in asked:
            try:
                predictions[name] = last.where(name, n=10, random_state=0).samples
            except UnknownNameError:
                pass
        plot_home_map(last.parameters, 0, None, last.vocabulary, map_image=image, map_extent=extent,
                      predicted_positions=predictions, title="CC4F (no camera), learnt on its own",
                      path=args.map)
        print(f"wrote {args.map}")


def _ros_map(yaml_file: Path) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """A ROS map (``map.yaml`` and its image) as an image array and its extent in metres
    (x_min, x_max, y_min, y_max): what ``spco show --map IMAGE --extent …`` takes."""
    import matplotlib.image

    fields = {}
    for line in yaml_file.read_text().splitlines():
        key, _, value = line.partition(":")
        fields[key.strip()] = value.strip()
    resolution = float(fields["resolution"])
    x0, y0 = (float(v) for v in fields["origin"].strip("[]").split(",")[:2])
    image = matplotlib.image.imread(yaml_file.parent / fields["image"])
    if image.ndim == 2:  # an occupancy grid in grey levels: drawn grey, not in a colour map
        image = np.repeat((image / max(float(image.max()), 1.0))[:, :, None], 3, axis=2)
    height, width = image.shape[:2]
    return image, (x0, x0 + width * resolution, y0, y0 + height * resolution)


def main() -> None:
    """Parse the command line and run one of the two benchmarks."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="which", required=True)
    drop = sub.add_parser("dropout", help="the general experiment with the new homes' views removed")
    drop.add_argument("--data", required=True)
    drop.add_argument("--regions", required=True)
    drop.add_argument("--out", required=True)
    drop.add_argument("--levels", type=float, nargs="+", default=list(LEVELS))
    drop.add_argument("--trials", type=int, default=10)
    drop.add_argument("--iterations", type=int, default=200)
    drop.add_argument("--jobs", type=int, default=1)
    drop.add_argument("--seed", type=int, default=0)
    drop.add_argument("--force", action="store_true", help="start over (default: resume each level)")
    cc = sub.add_parser("cc4f", help="CC4F learnt on its own")
    cc.add_argument("--data", required=True)
    cc.add_argument("--seeds", type=int, default=5)
    cc.add_argument("--iterations", type=int, default=200)
    cc.add_argument("--adapt-iterations", type=int, default=100)
    cc.add_argument("--prior", default="places", choices=("places", "scaled", "paper"),
                    help="fit_knowledge's prior (default: places, as spco fit)")
    cc.add_argument("--concepts", type=int, default=None, help="L (default: the paper's 15)")
    cc.add_argument("--regions", type=int, default=None, help="K (default: the paper's 20)")
    cc.add_argument("--kappa0", type=float, default=None, help="κ0 (default: the paper's 0.05)")
    cc.add_argument("--map", default=None, help="draw the home on map.yaml's map into this PNG")
    args = parser.parse_args()
    (run_dropout if args.which == "dropout" else run_cc4f)(args)


if __name__ == "__main__":
    main()
