"""Synonyms (issue 13, point 4): several names for one place each find it, and `what` lists them.

Two parts (docs/model.md, "Synonyms"): names one home says at the same places start as one concept
(:func:`spco.model.synonyms.same_place_names`), and a concept a home does not use is looked for at
the occupied concept its views fit best (:func:`spco.model.position_prediction.concept_stand_ins`).
"""

from __future__ import annotations

import numpy as np

from spco.data.language import Vocabulary
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.evaluation import evaluate_home
from spco.model import SpCoTransfer
from spco.model.parameters import ConceptParameters
from spco.model.position_prediction import concept_stand_ins, region_posterior_for_name
from spco.model.prediction import predict_names
from spco.model.synonyms import name_overlaps, name_region_overlaps, pooled_overlaps, same_place_names


def test_names_said_at_the_same_regions_are_one_place() -> None:
    # columns: 0 bath, 1 bathroom, 2 kitchen, 3 dining; K = 4 regions, three homes
    home0 = ([0, 0, 1, 1, 1, 2, 2, 3, 3], [0, 0, 0, 0, 1, 2, 2, 3, 3])  # bath & bathroom share regions
    home1 = ([0, 1, 1, 2, 2, 3, 3, -1], [1, 1, 1, 2, 2, 3, 3, 1])  # and again; kitchen, dining apart
    home2 = ([2, 2, 3, 3, 0], [2, 2, 2, 2, 0])  # an open-plan kitchen-diner: one region for both
    names = np.array(home0[0] + home1[0] + home2[0])
    regions = np.array(home0[1] + home1[1] + home2[1])
    offsets = np.array([0, 9, 17, 22])
    pooled = pooled_overlaps(name_region_overlaps(names, regions, offsets, 4), 4).toarray()
    assert pooled[0, 1] > 0.4 and pooled[2, 3] < 0.4  # kitchen/dining: apart in 2 of 3 homes
    out = same_place_names(names, regions, offsets, n_regions=4, n_words=4)
    # bath and bathroom are one group in each home, named by the home's most said of them
    assert (out[:5] == 1).all() and (out[9:12] == 1).all()
    # kitchen and dining stay apart, even in the home that says them in one region
    assert list(out[5:9]) == [2, 2, 3, 3] and list(out[17:21]) == [2, 2, 3, 3]
    assert out[16] == -1 and out[21] == 0  # no name stays none; a name alone stays itself


def test_the_overlaps_add_up_over_shards() -> None:
    """A fit whose homes are split over shards (the Ray engine's start, spco.model.shard_init) pools
    the overlaps over every home: each shard's sums added up give the one-process grouping."""
    rng = np.random.default_rng(4)
    sizes = [9, 7, 12, 6, 10]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    names = rng.integers(-1, 5, offsets[-1])
    regions = rng.integers(0, 4, offsets[-1])
    whole = name_overlaps(name_region_overlaps(names, regions, offsets, 4), 5)
    cut = 2  # shards: homes 0-1 and homes 2-4
    rows = offsets[cut]
    parts = [name_overlaps(name_region_overlaps(names[:rows], regions[:rows], offsets[:cut + 1], 4), 5),
             name_overlaps(name_region_overlaps(names[rows:], regions[rows:], offsets[cut:] - rows, 4), 5)]
    summed = parts[0] + parts[1]
    assert np.allclose(summed.pooled().toarray(), whole.pooled().toarray())
    assert summed.nbytes > 0
    for threshold in (0.2, 0.4, 0.6):
        one = same_place_names(names, regions, offsets, 4, 5, min_overlap=threshold)
        first = same_place_names(names[:rows], regions[:rows], offsets[:cut + 1], 4, 5, threshold, summed)
        second = same_place_names(names[rows:], regions[rows:], offsets[cut:] - rows, 4, 5, threshold, summed)
        assert np.array_equal(np.concatenate([first, second]), one)


def _params(occupied: list[bool]) -> ConceptParameters:
    """One home, concepts 0 (views like the bath, word "bathroom", region 0), 1 (other views,
    region 1) and 2 (bath views, word "bath"; holds samples of this home or not)."""
    theta_v = np.array([[[0.9, 0.1], [0.1, 0.9], [0.85, 0.15]]])
    theta_w = np.array([[[1.0 - 1e-9, 1e-9], [1.0 - 1e-6, 1e-6], [1e-9, 1.0 - 1e-9]]])
    return ConceptParameters(
        concept_weights=np.array([[0.4, 0.4, 0.2]]),
        region_weights=np.array([[[0.98, 0.02], [0.02, 0.98], [0.5, 0.5]]]),
        region_means=np.array([[[0.0, 0.0, 0.0, 1.0], [5.0, 0.0, 0.0, 1.0]]]),
        region_covariances=np.tile(np.eye(4) * 0.1, (1, 2, 1, 1)),
        word_probabilities=theta_w, visual_probabilities=theta_v,
        shared_word_probabilities=theta_w[0], shared_visual_probabilities=theta_v[0],
        global_concept_weights=np.array([0.4, 0.4, 0.2]), word_mask=np.ones(2, dtype=bool),
        region_counts=np.array([[10, 10]]),
        concept_counts=np.array([[10.0, 10.0, 10.0 if occupied[2] else 0.0]]))


def test_a_concept_the_home_does_not_use_is_looked_for_where_its_views_are() -> None:
    vocabulary = Vocabulary(("bathroom", "bath"))
    params = _params([True, True, False])
    assert list(concept_stand_ins(params, 0)) == [0, 1, 0]
    # "bath" is carried by concept 2, which holds no sample here: it is found where concept 0 is
    # (before: among the occupied concepts, concept 1's θ^w of 1e-6 beat concept 0's 1e-9)
    assert np.argmax(region_posterior_for_name(params, 0, vocabulary, "bath")) == 0
    assert np.argmax(region_posterior_for_name(params, 0, vocabulary, "bathroom")) == 0
    # a concept the home uses stands for itself
    assert list(concept_stand_ins(_params([True, True, True]), 0)) == [0, 1, 2]


def test_synonyms_of_free_speech_find_their_places_in_a_new_home() -> None:
    """8 homes whose households talk freely (several names per place, each household its own mix:
    :mod:`spco.data.speech`) and a new home taught nothing: `where` for every accepted name of a
    place (A_p averages them) and `what`'s top 3 at the new home's test samples."""
    positions, accepted_in_top = [], []
    for seed in (0, 1, 2):
        corpus = generate_homes(9, seed=seed, new_homes=1, specific_rooms=False,
                                config=SyntheticConfig(n_features=256, language="free"))
        model = SpCoTransfer(n_iterations=30, random_state=0, prune_words=True).fit(corpus)
        e, env = len(corpus) - 1, corpus[-1]
        scores = evaluate_home(model.parameters_, e, env, corpus.vocabulary, rng=0,
                               view_counts=model.settings_.view_counts)
        positions.append(scores.mean_position_accuracy)
        gt = env.ground_truth
        rows = np.flatnonzero(env.is_test)
        top = predict_names(model.parameters_, e, corpus.vocabulary, env.positions[rows], env.visual[rows],
                            top_k=3, view_counts=model.settings_.view_counts)
        accepted_in_top += [len(set(gt.accepted(gt.labels[i])) & set(words))
                            for i, words in zip(rows, top.words, strict=True)]
    # observed: A_p 0.86 / 0.81 / 0.55 (mean 0.74), accepted names in the top 3: 1.36 on average;
    # fit seeds 0-7: A_p 0.70-0.76, top 3 1.08-1.50, 7 of 8 passing (seed 1: 1.08). On main after the
    # held-out merge (one name per taught sentence) this was a known failure at fit seed 0 (top 3
    # 1.06; seeds 0-7: 5 of 8 passing); the vocabulary of branch names (terms from distinct
    # sentences, words never said apart joined) gives it back.
    # Before one name per taught sentence: A_p 0.83 / 0.49 / 0.72 (mean 0.68), top 3 1.28.
    # Before (one concept per synonym, and `where` looking among the home's concepts only):
    # A_p 0.32 / 0.42 / 0.46 (mean 0.40), 0.92 accepted names in the top 3
    assert np.mean(positions) >= 0.6, positions
    assert np.mean(accepted_in_top) >= 1.15, np.mean(accepted_in_top)
