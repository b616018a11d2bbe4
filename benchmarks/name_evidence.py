"""Fit the weights of the name evidence (:data:`spco.model.name_evidence.WEIGHTS`) on development data.

Every vocabulary token of four development corpora is one example, labelled 1 when it is an
accepted name of some place of its corpus and 0 otherwise:

1. ``benchmarks/development/speech_dev.csv`` (its vocabulary learnt from the 432 sentences said
   four times each, as the SIGVerse homes say them), labels ``accepted_names_dev.json``;
2. the hand-written SIGVerse sentences (``tests/data/handwritten_sigverse.csv``), labels the place
   labels and ``tests/test_handwritten.ACCEPTED``;
3. the free-form synthetic homes of seeds 0 and 1 (16 experienced homes each, as
   ``spco experiment general --data synthetic --language free``), labels their accepted names;
4. the SIGVerse template sentences of the paper's 16 experienced homes, labels the place labels.

Logistic regression with an L2 penalty (``--penalty``, on the weights, not the intercept). The
frozen :data:`~spco.model.name_evidence.WEIGHTS` were fitted with ``--terms-from all`` (the
default: each corpus's terms learnt from all its sentences, as spco did before it counted distinct
sentences only); ``--terms-from distinct`` fits on today's vocabularies. Prints
the weights to paste into ``name_evidence.py``, each corpus's tokens ranked by P(name), and the
leave-one-corpus-out log loss. Never run on held-out data::

    python benchmarks/name_evidence.py --sigverse ../shared/datasets/sigverse
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from data_paths import SIGVERSE

from spco.data.language import Vocabulary, learn_terms, normalize_name
from spco.data.loading import load
from spco.data.speech import accepted_names
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.evaluation.experiments import PAPER_EXPERIENCED_HOMES
from spco.model.name_evidence import FEATURES, feature_matrix

ROOT = Path(__file__).resolve().parents[1]


#: The development homes of people's real sentences (benchmarks/SPLIT.md, "Natural speech").
SUBJECT_DEVELOPMENT = ("1LDK_1", "1LDK_3", "1LDK_5", "1LDK_7", "2LDK_1", "2LDK_3", "2LDK_5", "2LDK_7")


def corpora(sigverse: Path, subject: Path | None = None) -> dict[str, tuple[list[str], set[str]]]:
    """name -> (sentences, accepted names). ``subject``: also people's sentences of the development
    homes (``sigverse_subject``; never the held-out homes), labelled by ``accepted_names_dev.json``."""
    out: dict[str, tuple[list[str], set[str]]] = {}
    dev = ROOT / "benchmarks" / "development"
    with open(dev / "speech_dev.csv", encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    accepted = json.loads((dev / "accepted_names_dev.json").read_text(encoding="utf-8"))
    names = {normalize_name(n) for k, v in accepted.items() if not k.startswith("_") for n in v}
    names |= {normalize_name(k) for k in accepted if not k.startswith("_")}
    out["speech_dev"] = ([r["sentence"] for r in rows] * 4, names)
    from test_handwritten import ACCEPTED, SENTENCES

    with open(SENTENCES, encoding="utf-8", newline="") as fh:
        hand = [r["sentence"] for r in csv.DictReader(fh)]
    labels = {"entrance", "toilet", "bath", "washroom", "kitchen", "dining", "living room", "bedroom"}
    out["handwritten"] = (hand, labels | {normalize_name(n) for v in ACCEPTED.values() for n in v})
    for seed in (0, 1):
        corpus = generate_homes(16, seed=seed, config=SyntheticConfig(language="free"))
        sentences = [s for env in corpus for s in env.training_data().sentences if s is not None]
        places = {p for env in corpus for p in env.ground_truth.places}  # type: ignore[union-attr]
        out[f"synthetic_free_{seed}"] = (sentences, {n for p in places for n in accepted_names(p)} | places)
    template = [s for name in PAPER_EXPERIENCED_HOMES for s in load(sigverse / name)[name].sentences
                if s is not None]
    out["templates"] = (template, labels)
    if subject is not None:
        from spco.data.sigverse import read_indexed_texts

        said = []
        for home in SUBJECT_DEVELOPMENT:
            n = len(list((subject / home / "per_100").glob("sentence*.txt")))
            texts = read_indexed_texts(subject / home / "per_100", "sentence", n, strict=False)
            said += [t for t in texts if t]
        out["subject_dev"] = (said, names)
    return out


def fit(x: np.ndarray, y: np.ndarray, penalty: float) -> np.ndarray:
    """Intercept and weights of an L2-penalised logistic regression."""
    design = np.hstack([np.ones((x.shape[0], 1)), x])

    def loss(w: np.ndarray) -> tuple[float, np.ndarray]:
        z = design @ w
        p = 1.0 / (1.0 + np.exp(-z))
        value = float(np.sum(np.logaddexp(0.0, z) - y * z) + 0.5 * penalty * np.sum(w[1:] ** 2))
        grad = design.T @ (p - y)
        grad[1:] += penalty * w[1:]
        return value, grad

    return minimize(loss, np.zeros(design.shape[1]), jac=True, method="L-BFGS-B").x


def main() -> None:
    """Fit and print."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--penalty", type=float, default=1.0)
    parser.add_argument("--subject", type=Path, default=None,
                        help="sigverse_subject: also fit on people's sentences of the development homes")
    parser.add_argument("--terms-from", choices=("all", "distinct"), default="all",
                        help="learn each corpus's terms from all its sentences (how the frozen WEIGHTS "
                             "were fitted, before Vocabulary.from_sentences counted distinct sentences "
                             "only) or from its distinct sentences (as spco does now)")
    args = parser.parse_args()
    data = {}
    for name, (sentences, names) in corpora(args.sigverse, args.subject).items():
        if args.terms_from == "all":
            terms = Vocabulary(tuple(learn_terms(s for s in sentences if s)))
            vocab = Vocabulary(tuple(dict.fromkeys(t for s in sentences for t in terms.tokenize(s))))
        else:
            vocab = Vocabulary.from_sentences(sentences)
        x = feature_matrix(vocab, sentences)
        y = np.array([float(w in names) for w in vocab.words])
        data[name] = (vocab, x, y)
        print(f"{name}: {len(vocab)} tokens, {int(y.sum())} names")
    x_all = np.vstack([d[1] for d in data.values()])
    y_all = np.concatenate([d[2] for d in data.values()])
    w = fit(x_all, y_all, args.penalty)
    print("WEIGHTS = (" + ", ".join(f"{v:.3f}" for v in w) + ")")
    for f, v in zip(("intercept", *FEATURES), w, strict=True):
        print(f"  {f:15s} {v:+.3f}")
    for name, (vocab, x, y) in data.items():
        rest = [k for k in data if k != name]
        w_out = fit(np.vstack([data[k][1] for k in rest]), np.concatenate([data[k][2] for k in rest]),
                    args.penalty)
        z = w_out[0] + x @ w_out[1:]
        loss = float(np.mean(np.logaddexp(0.0, z) - y * z))
        p = 1.0 / (1.0 + np.exp(-(w[0] + x @ w[1:])))
        order = np.argsort(-p)
        top = ", ".join(f"{vocab.words[k]}{'*' if y[k] else ''} {p[k]:.2f}" for k in order[:25])
        print(f"\n{name}: held-out-corpus log loss {loss:.3f}\n  top: {top}")
        low_names = ", ".join(f"{vocab.words[k]} {p[k]:.2f}" for k in order if y[k] and p[k] < 0.5)
        print(f"  names below 0.5: {low_names}")


if __name__ == "__main__":
    main()
