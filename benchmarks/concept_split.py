"""Why people who name only objects become a concept of their own (issue 28, class a2 of
``speech_errors.py``): how many nats separate, for an object-only sentence, the concept it sits in
from the concept most of its place's namers sit in, and from which term.

Development side only (``benchmarks/SPLIT.md``, "Natural speech"): the 3LDK_9 configuration of
``natural_speech.py`` (knowledge from the 8 development homes' people's sentences, new home 3LDK_9
untaught), one fit (``--seed``, the trial seed of ``natural_speech.py``'s first configuration). For
every taught sample of the knowledge homes whose sentence says no name of its place
(``accepted_names_dev.json`` and ``speech_errors.CALLED_BUT_NOT_ACCEPTED``) and that sits in another
concept than the one most of the place's namers sit in, the differences of the terms of the concept
draw at the fit's last state (its concept − the namers' concept):

- **words**: the switches marginalised, each token at its weight (``mixture_log_likelihood``: W^w
  counts per token, ``TransferHyperparameters.word_counts``; S^w with ``--set word_counts=none``);
- **view**: the view's log-likelihood at the view weight w;
- **position**: log Σ_r π_{e,l,r} N(x | r);
- **G_e**: log G_{e,l}.

Printed: the concepts (taught samples, their three most frequent places and the share of each
place's samples there that name it), then per place the median differences, the words' per token
and the log ratio per token (÷ the token's weight), and the views' 10–90 % range.

    nice -n 5 python benchmarks/concept_split.py --sweeps 60 [--set word_counts=none]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
from scipy.special import logsumexp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from data_paths import SIGVERSE
from free_speech import fit_new_home, read_names, settings_hyperparameters
from natural_speech import configurations
from speech_errors import training_places
from split_seeds import refuse_other_seeds

from spco.model.assignments import view_weights
from spco.model.observations import GaussianRegions, HierarchicalMultinomial
from spco.model.word_channels import mixture_log_likelihood


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sigverse", type=Path, default=SIGVERSE)
    parser.add_argument("--accepted", type=Path,
                        default=Path(__file__).resolve().parent / "development" / "accepted_names_dev.json")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sweeps", type=int, default=60)
    parser.add_argument("--set", nargs="+", action="extend", default=[], metavar="NAME=VALUE")
    return parser


def terms(model) -> dict[str, np.ndarray]:
    """The concept draw's terms at the fit's last state, (N, L) each."""
    data, state = model.data_, model.state_
    if state.channels is None:
        raise SystemExit("the fit has no word channels (speech without English function words?)")
    view = HierarchicalMultinomial.log_likelihood(data.visual, data.homes, state.log_theta_v)
    weights = view_weights(data, model.settings_.view_counts)
    if weights is not None:
        view = view * weights[:, None]
    region = GaussianRegions.log_likelihood(data.positions, data.homes, state.means, state.covariances)
    return {"words": mixture_log_likelihood(data.words, data.homes, state.log_theta_w, state.channels),
            "view": view,
            "position": logsumexp(state.log_pi[data.homes] + region[:, None, :], axis=2),
            "G_e": state.log_g[data.homes]}


def main() -> None:
    """Fit the 3LDK_9 configuration once and print the terms that split the namers from the others."""
    parser = _parser()
    args = parser.parse_args()
    refuse_other_seeds(parser, [args.seed])
    accepted = read_names(args.accepted)
    _, configs = configurations(args.sigverse, accepted)
    _, homes, env = configs[0]
    model, corpus = fit_new_home(homes, env, settings_hyperparameters(args.set), args.sweeps, args.seed, 0)
    parts = terms(model)
    data, concepts = model.data_, model.state_.concepts
    samples = [sample for h in corpus for sample in training_places(h, corpus.vocabulary, accepted)]
    place_of = np.array([place for place, _ in samples], dtype=object)
    named = [said for _, said in samples]
    taught = np.array([n is not None for n in named]) & (data.homes < len(corpus) - 1)
    print(f"word_counts {model.hyperparameters_.word_counts}, token weight "
          f"{model.state_.channels.token_weight:g}; concepts: taught samples, places (share naming it)")
    for c in np.unique(concepts[taught]):
        rows = np.flatnonzero(taught & (concepts == c))
        shares = [f"{p}: {n} ({np.mean([named[i] for i in rows[place_of[rows] == p]]):.2f})"
                  for p, n in Counter(place_of[rows]).most_common(3)]
        print(f"  {c}: {rows.size}, " + ", ".join(shares))
    tokens = np.diff(data.words.indptr)
    found: dict[str, list[dict[str, float]]] = defaultdict(list)
    for place in sorted(set(place_of[taught])):
        rows = np.flatnonzero(taught & (place_of == place))
        namers = rows[[bool(named[i]) for i in rows]]
        if not namers.size:
            continue
        theirs = Counter(concepts[namers]).most_common(1)[0][0]
        for t in rows:
            if not named[t] and concepts[t] != theirs:
                found[place].append({k: float(v[t, concepts[t]] - v[t, theirs]) for k, v in parts.items()}
                                    | {"tokens": float(tokens[t])})
    print("\n| place (samples) | words | view | position | G_e | words per token | log ratio per token | "
          "view 10–90 % |\n|---|---:|---:|---:|---:|---:|---:|---|")
    for place, rows in sorted(found.items(), key=lambda kv: -np.median([d["words"] for d in kv[1]])):
        med = {k: np.median([d[k] for d in rows]) for k in ("words", "view", "position", "G_e")}
        per_token = np.median([d["words"] / max(d["tokens"], 1) for d in rows])
        counts = model.state_.channels.token_weight * model.word_increment_  # a token's weight
        low, high = np.percentile([d["view"] for d in rows], [10, 90])
        print(f"| {place} ({len(rows)}) | {med['words']:,.1f} | {med['view']:.1f} | {med['position']:.1f} | "
              f"{med['G_e']:.1f} | {per_token:,.2f} | {per_token / counts:.2f} | "
              f"[{low:.1f}, {high:.1f}] |")


if __name__ == "__main__":
    main()
