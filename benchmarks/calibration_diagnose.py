"""Why is `what` wrong *and* sure? The cause of every wrong answer at p ≥ 0.99, development views only.

Reads the models and answers of a ``benchmarks/calibration.py --sets development-new`` (or
``development``) run (``--models OUT``: its ``--out``) and puts each wrong answer given at p ≥ 0.99
into the first of these classes that fits (``benchmarks/calibration/SPLIT.md``: development views
only; a held-out run's rows are refused):

- ``mask``: the right name is not among the names the home answers (``HomeModel.name_mask``);
- ``merged``: the view's room — the home's training samples with the view's label — is, by the
  majority of its samples' concepts after ``adapt``, in a concept that also holds the majority of
  another room of the home: two rooms, one concept, and the concept is named for the other room;
- ``misnamed``: the room has a concept of its own, but that concept's name (p(name | concept), the
  answer's parameters) is not the room's;
- ``view``: the room's concept names it right, and the position alone answers right; the view
  overrides it (the view's weight);
- ``position``: the room's concept names it right, the view alone answers right, the position
  overrides it (the position term);
- ``other``: neither alone answers right.

Printed per configuration (features × experienced homes): the number of answers, of wrong answers,
of wrong answers at p ≥ 0.99, and their classes; then each merged room (home, room, the concept's
name, the rooms sharing it, seeds). Same seed, same result (nothing is sampled).

    python benchmarks/calibration_diagnose.py --data D/sigverse --images D/sigverse_images --models /tmp/cal
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections import Counter, defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import calibration as cal

CLASSES = ("mask", "merged", "misnamed", "view", "position", "other")


def _names(params: Any, mask: np.ndarray, words: list[str]) -> list[str]:
    """The name each concept answers (argmax of p(name | concept) over the home's names)."""
    theta = np.asarray(params.word_probabilities[0], dtype=np.float64) * mask[None, :]
    return [words[int(np.argmax(row))] if row.sum() > 0 else "-" for row in theta]


def diagnose_home(home: Any, model: Any) -> list[dict[str, Any]]:
    """Every scored view of ``home`` with the answer, its probability and its class (module docstring;
    ``cls`` is ``None`` for answers that are right or below p 0.99)."""
    from spco.knowledge.queries import answer_parameters, name_prediction

    positions, visual, labels, ids = cal.scored_views(home)
    params = answer_parameters(model)
    mask = np.asarray(model.name_mask, dtype=bool)
    words = list(model.vocabulary.words)
    concept_name = _names(params, mask, words)
    # each room's (label's) majority concept among the adapted home's training samples
    label_of = dict(zip(home.ids.tolist(), home.labels(), strict=True))
    room_concepts: dict[str, Counter] = defaultdict(Counter)
    for sample, concept in zip(model.ids.tolist(), np.asarray(model.state.concepts).tolist(), strict=True):
        if label_of.get(sample) is not None:
            room_concepts[label_of[sample]][int(concept)] += 1
    majority = {room: c.most_common(1)[0][0] for room, c in room_concepts.items()}
    full = name_prediction(model, positions, visual, top_k=1)
    alone_position = name_prediction(model, positions, None, top_k=1)
    from spco.model.prediction import predict_names

    alone_view = predict_names(params, 0, model.vocabulary, positions, visual, top_k=1,
                               weighting=model.weighting,  # type: ignore[arg-type]
                               use_position=False, view_counts=model.hyperparameters.view_weight())
    rows = []
    for i, label in enumerate(labels):
        answer, p = full.best[i], float(full.confidence[i])
        cls = None
        concept = majority.get(label)
        sharing = sorted(r for r, c in majority.items() if c == concept and r != label)
        if answer != label and p >= cal.SURE:
            if label not in words or not mask[words.index(label)]:
                cls = "mask"
            elif concept is not None and concept_name[concept] != label and sharing:
                cls = "merged"
            elif concept is not None and concept_name[concept] != label:
                cls = "misnamed"
            elif alone_position.best[i] == label:
                cls = "view"
            elif alone_view.best[i] == label:
                cls = "position"
            else:
                cls = "other"
        rows.append({"home": home.name, "view": int(ids[i]), "label": label, "answer": answer, "p": p,
                     "cls": cls, "room_concept": concept,
                     "room_concept_name": None if concept is None else concept_name[concept],
                     "sharing": sharing, "position_alone": alone_position.best[i],
                     "view_alone": alone_view.best[i]})
    return rows


def main(argv: Sequence[str] | None = None) -> None:
    """Print the table (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--images", type=Path, default=None)
    parser.add_argument("--models", type=Path, required=True, help="a calibration.py --out (development)")
    parser.add_argument("--json", type=Path, default=None, help="write every classified answer here")
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    import spco.knowledge as kn

    found = sorted((args.models / "models").glob("home_*.spco"))
    tasks: dict[tuple[str, int], list[tuple[int, str, Path]]] = defaultdict(list)
    for path in found:
        # home names hold "_" (2LDK_3): the stem is home_<features>_<size>_<seed>_<home>
        parts = path.stem[len("home_"):].split("_")
        features, size, seed, home = parts[0], int(parts[1]), int(parts[2]), "_".join(parts[3:])
        if home in cal.SETS["held-out"]["homes"]:
            raise SystemExit(f"error: {path} is a held-out home; this diagnosis reads development views only")
        tasks[(features, size)].append((seed, home, path))
    everything = []
    for (features, size), items in sorted(tasks.items()):
        counts: Counter = Counter()
        answers = wrong = 0
        merges: dict[tuple[str, str, str, tuple[str, ...]], list[int]] = defaultdict(list)
        for seed, name, path in sorted(items):
            home = cal._load(args.data, args.images, [name], features, 0)[0]
            rows = diagnose_home(home, kn.load_home_model(path))
            for r in rows:
                r.update({"features": features, "size": size, "seed": seed})
            everything += rows
            answers += len(rows)
            wrong += sum(r["answer"] != r["label"] for r in rows)
            for r in rows:
                if r["cls"] is not None:
                    counts[r["cls"]] += 1
                    if r["cls"] == "merged":
                        key = (name, r["label"], r["room_concept_name"], tuple(r["sharing"]))
                        if seed not in merges[key]:
                            merges[key].append(seed)
        sure = sum(counts.values())
        print(f"{features}, {size} homes: {answers} answers, {wrong} wrong, {sure} wrong at p >= 0.99: "
              + ", ".join(f"{c} {counts[c]}" for c in CLASSES), flush=True)
        for (name, room, said, sharing), seeds in sorted(merges.items()):
            print(f"    merged: {name} {room} answered {said!r} (its concept holds {', '.join(sharing)}), "
                  f"seeds {seeds}")
    if args.json is not None:
        args.json.write_text("\n".join(json.dumps(r) for r in everything) + "\n")


if __name__ == "__main__":
    main()
