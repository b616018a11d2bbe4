"""Digests of a home's state along its whole path, to show that a change leaves a setting's results
byte-identical: run it with one tree's ``src`` and with another's (e.g. ``git archive main src``
extracted) and compare the JSON.

For each setting (the default ``place_channel="shared"`` and ``place_channel="home"``): an
:class:`~spco.model.SpCoTransfer` fit of four synthetic free-speech homes (``generate_homes(5, seed=0,
new_homes=1, language="free", n_features=64)``, 8 sweeps, seed 0), ``fit_knowledge`` of them (8 sweeps,
seed 0) and its file, ``adapt`` of the fifth home (4 sweeps, seed 0), a ``teach`` ("this is the quokka
room" at its fourth sample, seed 1), its home file and that file loaded; with the default also a shard
checkpoint after 3 sweeps. Each digest is the first 16 hex digits of a SHA-256: of a state (concepts,
regions, θ^w, θ^v, G, means, switches, ψ_l, β, shares, the homes' ψ_{e,l}), of every array of a
:class:`~spco.model.parameters.ConceptParameters`, or of a file's arrays and its header without times,
checksums, versions of spco and provenance (``/v<n>``: the file's format version); and of the
answers (the joint fit's ``predict_names`` and ``evaluate_answers`` in its fourth home, the taught
home's ``what`` at every sample and ``ask``'s question scores).

    PYTHONPATH=src python tools/state_digests.py --folder /tmp/digests > branch.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import warnings
from pathlib import Path

import numpy as np

from spco import knowledge as kn
from spco.data.environment import Corpus
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.engines import LocalEngine, checkpoints
from spco.model import SpCoTransfer
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.sources import SyntheticHomes
from spco.model.word_channels import WordChannels

_VOLATILE = ("created", "updated", "checksum", "array_checksums", "provenance", "knowledge_provenance",
             "spco_version")


def _digest(*arrays: object) -> str:
    d = hashlib.sha256()
    for a in arrays:
        d.update(b"none" if a is None else np.ascontiguousarray(a).tobytes())
    return d.hexdigest()[:16]


def state_digest(state) -> str:
    """The digest of a :class:`~spco.model.state.GibbsState` (module docstring)."""
    c = state.channels
    parts = (None if c is None else getattr(c, n) for n in ("log_place", "log_background", "log_shares",
                                                             "log_place_home"))
    return _digest(state.concepts, state.regions, state.log_theta_w, state.log_theta_v, state.log_g,
                   state.means, state.switches, *parts)


def file_digest(path: Path) -> str:
    """The digest of a knowledge or home file's arrays and header (module docstring), ``/v<version>``."""
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files if k != "header"}
        header = json.loads(bytes(f["header"]).decode())
    for k in _VOLATILE:
        header.pop(k, None)
    text = hashlib.sha256(json.dumps(header, sort_keys=True).encode()).hexdigest()[:16]
    return f"{_digest(*(arrays[k] for k in sorted(arrays)))}/{text}/v{header.get('format_version')}"


def answers_digest(model, env) -> str:
    """The digest of a joint fit's answers in its fourth home: ``predict_names`` at every sample (its
    probabilities) and ``evaluate_answers``' names and positions (seed 0)."""
    from spco.evaluation.metrics import evaluate_answers

    pred = model.predict_names(3, env.positions, env.visual, top_k=3)
    scores = evaluate_answers(model, 3, env, rng=0)
    samples = [scores.position_predictions[p].samples for p in sorted(scores.position_predictions)]
    return _digest(pred.word_probabilities, pred.confidence, scores.name_predictions.word_probabilities,
                   np.array([scores.position_accuracy[p] for p in scores.places]), *samples)


def home_answers_digest(home) -> str:
    """The digest of a home's answers: ``what`` at every sample (``name_prediction``, its
    probabilities and unsure flags) and ``ask``'s question scores (the concept posterior it ranks by)."""
    from spco.knowledge.asking import home_question_scores

    pred = kn.name_prediction(home, home.positions, home.visual, top_k=3)
    scores = home_question_scores(home)
    return _digest(pred.word_probabilities, pred.unsure, scores.gain, scores.model_probabilities,
                   scores.errors)


def digests(folder: Path) -> dict[str, str]:
    """Every digest of the module docstring; the files are written to ``folder``."""
    warnings.simplefilter("ignore")
    out: dict[str, str] = {}
    corpus = generate_homes(5, seed=0, new_homes=1, specific_rooms=False,
                            config=SyntheticConfig(n_features=64, language="free"))
    envs = list(corpus)
    for label, hyper in (("shared", TransferHyperparameters()),
                         ("home", TransferHyperparameters().with_settings(["place_channel=home"]))):
        model = SpCoTransfer(hyper, n_iterations=8, random_state=0, prune_words=True).fit(Corpus(envs[:4]))
        out[f"{label} fit state"] = state_digest(model.state_)
        out[f"{label} fit parameters"] = _digest(*model.parameters_.arrays().values())
        out[f"{label} fit answers"] = answers_digest(model, envs[3])
        knowledge = kn.fit_knowledge(Corpus(envs[:4]), n_iterations=8, random_state=0, hyperparameters=hyper)
        out[f"{label} knowledge file"] = file_digest(knowledge.save(folder / f"{label}.knowledge.spco",
                                                                    overwrite=True))
        home = kn.adapt(knowledge, envs[4], n_iterations=4, random_state=0)
        out[f"{label} adapt state"] = state_digest(home.state)
        out[f"{label} adapt posterior"] = _digest(*home.posterior.arrays().values())
        out[f"{label} adapt parameters"] = _digest(*home.parameters.arrays().values())
        taught = kn.teach(home, {int(home.ids[3]): "this is the quokka room"}, random_state=1)
        out[f"{label} teach state"] = state_digest(taught.state)
        out[f"{label} teach parameters"] = _digest(*taught.parameters.arrays().values())
        out[f"{label} teach answers"] = home_answers_digest(taught)
        path = taught.save(folder / f"{label}.home.spco", overwrite=True)
        out[f"{label} home file"] = file_digest(path)
        loaded = kn.load_home_model(path)
        out[f"{label} home file loaded state"] = state_digest(loaded.state)
        out[f"{label} home file loaded parameters"] = _digest(*loaded.parameters.arrays().values())
    source = SyntheticHomes.create(3, seed=2, new_homes=1,
                                   config=SyntheticConfig(n_features=32, n_train=12, language="free"))
    model = SpCoTransfer(TransferHyperparameters(), random_state=0, prune_words=True)
    hyper = model.checked_hyperparameters()
    run = LocalEngine(1).start_source(source, hyper, model.sampler_settings(), np.random.default_rng(5))
    run.use_word_channels(WordChannels.initial(np.full(len(source.vocabulary), 0.5), hyper.n_concepts))
    for i in range(3):
        run.sweep(i)
    path = folder / "shard.npz"
    checkpoints.save_shard(path, run.shards[0].state, run.shards[0].rng_states())
    with np.load(path) as f:
        out["shared shard checkpoint"] = _digest(*(f[k] for k in sorted(f.files)))
    run.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--folder", type=Path, required=True, help="where the files are written")
    args = parser.parse_args()
    args.folder.mkdir(parents=True, exist_ok=True)
    print(json.dumps(digests(args.folder), indent=1))


if __name__ == "__main__":
    main()
