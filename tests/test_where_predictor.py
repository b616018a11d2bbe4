"""One p(pose | name) (issue 29): the robot's `where` and the experiments' A_p answer from the same
function, :func:`spco.model.position_prediction.region_posterior_for_name`, with the same parameters
(the names `what` answers) and the same rooms (the room account); its formula checked by hand."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from serve_helpers import build_home

from spco import knowledge as kn
from spco.data.language import Vocabulary
from spco.errors import ConfigurationError
from spco.evaluation import evaluate_home
from spco.model import SpCoTransfer, position_prediction
from spco.model.answer_settings import AnswerSettings
from spco.model.confidence import model_answer_parameters
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.parameters import ConceptParameters
from spco.model.prediction import UnknownNameError
from spco.model.rooms import model_rooms, room_concepts

SMALL = TransferHyperparameters(n_concepts=6, n_regions=8)


@pytest.fixture(scope="module")
def home(tmp_path_factory: pytest.TempPathFactory) -> kn.HomeModel:
    return kn.load_home_model(build_home(tmp_path_factory.mktemp("where_predictor")))


@pytest.fixture(scope="module")
def joint(small_corpus):
    return SpCoTransfer(SMALL, prune_words=True, n_iterations=10, random_state=2).fit(small_corpus)


class _Spy:
    """Wraps ``_region_posterior`` (the one p(region | name): ``region_posterior_for_name`` and
    ``predict_positions`` call it): records whether each call had the home's rooms."""

    def __init__(self) -> None:
        self.original = position_prediction._region_posterior
        self.calls: list[tuple[object, object, np.ndarray]] = []

    def __call__(self, params, e, vocabulary, name, forms, mask, rooms, view_counts):
        result = self.original(params, e, vocabulary, name, forms, mask, rooms, view_counts)
        self.calls.append((params, rooms, result))
        return result


def _forms_by_hand(vocabulary, name: str, columns: list[int], lookup) -> list[list[int]]:
    """The words that say each token asked for: a name of one token is said by itself and by every
    usable word of several words holding it (" dining " inside " dining room "); a name of several
    tokens (known or not) by its known tokens, one each."""
    if len(columns) != 1 or len(vocabulary.query(name)[0]) != 1:
        return [[k] for k in columns]
    k = columns[0]
    word = f" {vocabulary.words[k]} "
    return [[k, *(j for j, w in enumerate(vocabulary.words)
                  if j != k and lookup[j] and " " in w and word in f" {w} ")]]


def _by_hand(params, rooms, view_counts, vocabulary, name, lookup, e: int = 0) -> np.ndarray:
    """p(m | w) ∝ Σ_k n_k [r(k) = m] Σ_l p(l | room k) Π_i Σ_c a_{c,w_i} (δ p_{c,l,w_i} + X_{c,k,w_i}) /
    (δ + T_{c,k}), worked out room by room and sample by sample (X: the name tokens, c = 0, and the
    place-word tokens, c = 1, said at the room's samples, each sample in its share)."""
    K = int(np.shape(params.region_means)[1])
    counts, posterior = room_concepts(params, e, rooms, view_counts)
    share, region_of = rooms.membership(K)
    share = share.toarray()
    columns = position_prediction.query_indices(params, vocabulary, name, lookup)
    forms = _forms_by_hand(vocabulary, name, columns, lookup)
    theta = np.asarray(params.word_probabilities[e])
    psi, prior = params.place_word_probabilities, params.word_channel_prior
    names = rooms.words if rooms.names is None else rooms.names
    said = [names.toarray(), None if rooms.places is None else rooms.places.toarray()]
    probs = [theta, None if psi is None else np.clip(np.asarray(psi), 0.0, 1.0)]
    delta = rooms.concentration
    out = np.zeros(K)
    for k in range(counts.size):
        for c in range(params.n_concepts):
            like = 1.0
            for form in forms:
                p_w = 0.0
                for w in form:
                    for ch in (0, 1):
                        if probs[ch] is None or (ch == 1 and prior is None):
                            continue
                        a = 1.0 if prior is None else prior[w][ch]
                        X = np.zeros(len(lookup))
                        if said[ch] is not None:
                            for i in range(rooms.regions.size):
                                X += share[k, i] * said[ch][i]
                        X = X * lookup
                        p_w += a * (probs[ch][c, w] if delta is None else
                                    (delta * probs[ch][c, w] + X[w]) / (delta + X.sum()))
                like *= p_w
            out[region_of[k]] += counts[k] * posterior[k, c] * like
    return out / out.sum()


def test_where_answers_from_the_one_function_with_the_rooms_and_names_of_what(
        home: kn.HomeModel, monkeypatch: pytest.MonkeyPatch) -> None:
    spy = _Spy()
    monkeypatch.setattr(position_prediction, "_region_posterior", spy)
    params, rooms = kn.queries.answer_inputs(home)  # what `what` reads
    assert home.known_names
    for name in home.known_names:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            answer = kn.where(home, name, n=4, random_state=0)
        called_params, called_rooms, result = spy.calls[-1]
        assert called_params is params and called_rooms is rooms  # the answer's parameters and rooms
        assert_allclose(answer.region_probabilities, result)
        expected = _by_hand(params, rooms, home.hyperparameters.view_weight(), home.vocabulary, name,
                            home.parameters.word_mask)
        assert_allclose(answer.region_probabilities, expected, atol=1e-12)
        assert answer.region == int(np.argmax(expected))


def test_the_experiments_a_p_draws_from_what_where_answers(joint, small_corpus,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """evaluate_home's positions come from the same function as `where`, with the robot's answer
    parameters and rooms: a scorer with an account of its own fails here."""
    e = len(small_corpus) - 1
    env = small_corpus[e]
    answer, rooms = model_answer_parameters(joint, e), model_rooms(joint, e)
    w = joint.settings_.view_counts
    spy = _Spy()
    monkeypatch.setattr(position_prediction, "_region_posterior", spy)
    scores = evaluate_home(joint.parameters_, e, env, joint.vocabulary_, rng=0, view_counts=w,
                           answer_params=answer, answer_rooms=rooms)
    assert scores.position_predictions, "no place's name was predicted"
    assert spy.calls and all(p is answer and r is rooms for p, r, _ in spy.calls)
    for place, pred in scores.position_predictions.items():
        expected = _by_hand(answer, rooms, w, joint.vocabulary_, pred.name, joint.parameters_.word_mask, e)
        assert_allclose(pred.region_probabilities, expected, atol=1e-12, err_msg=place)
        direct = position_prediction.predict_positions(answer, e, joint.vocabulary_, pred.name, n=3, rng=0,
                                                       unheard=False, rooms=rooms, view_counts=w,
                                                       lookup=joint.parameters_.word_mask)
        assert_allclose(direct.region_probabilities, pred.region_probabilities)


def test_answer_regions_draw_the_regions_at_least_half_as_probable_as_the_best() -> None:
    regions = position_prediction.answer_regions(np.array([0.1, 0.45, 0.05, 0.4]), 10)
    assert regions[0] == 1 and set(regions.tolist()) == {1, 3}
    assert (regions == 1).sum() == 5 and (regions == 3).sum() == 5
    assert position_prediction.answer_regions(np.array([0.2, 0.8]), 0).size == 0
    assert set(position_prediction.answer_regions(np.array([0.5, 0.5]), 1).tolist()) <= {0, 1}


def test_a_taught_room_is_found_by_its_name_through_the_rooms(home: kn.HomeModel) -> None:
    """The home's teachings enter through the room account (its taught names decide the room's concept),
    the answer's θ^w and the room's own names: a new name taught at one sample is found in that sample's
    region, learnt."""
    row = 3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        taught = kn.teach(home, {int(home.ids[row]): "this is the quokka room"}, random_state=0)
        answer = kn.where(taught, "quokka room", n=6, random_state=0)
    assert answer.learnt
    assert int(taught.state.regions[row]) in answer.regions.tolist() or \
        kn.queries.answered_at_region(taught, answer.region) == "quokka room"
    assert not hasattr(kn, "WHERE_MODEL_WEIGHT") and not hasattr(kn.queries, "WHERE_ANYWHERE_WEIGHT")


def _beta_mean_by_quadrature(a: float, b: float, hits: float, misses: float) -> float:
    """E[φ | hits of w among hits + misses tokens], φ ~ Beta(a, b): the posterior worked out on a grid
    (prior density × likelihood, normalised numerically), not from conjugacy."""
    phi = np.linspace(0.0, 1.0, 400_001)[1:-1]
    log_post = (a - 1 + hits) * np.log(phi) + (b - 1 + misses) * np.log1p(-phi)
    post = np.exp(log_post - log_post.max())
    return float(np.trapezoid(phi * post, phi) / np.trapezoid(post, phi))


def _tiny_home(mask: list[bool]) -> tuple[ConceptParameters, Vocabulary]:
    """One home, 3 concepts, 3 regions, the words "dining", "dining room", "dining table", "kitchen"
    and "kitchen sink": a concept's names, its regions and G drawn at random (fixed seed)."""
    rng = np.random.default_rng(7)
    vocabulary = Vocabulary(("dining", "dining room", "dining table", "kitchen", "kitchen sink"))
    L, K, V, D = 3, 3, len(vocabulary), 2
    theta = rng.dirichlet(np.ones(V), size=L)[None]
    params = ConceptParameters(
        concept_weights=rng.dirichlet(np.ones(L))[None],
        region_weights=rng.dirichlet(np.ones(K), size=L)[None],
        region_means=np.column_stack([np.arange(K) * 3.0, np.zeros(K), np.zeros(K), np.ones(K)])[None],
        region_covariances=np.tile(np.eye(4) * 0.1, (1, K, 1, 1)), word_probabilities=theta,
        visual_probabilities=np.full((1, L, D), 0.5), shared_word_probabilities=theta[0],
        shared_visual_probabilities=np.full((L, D), 0.5), global_concept_weights=np.full(L, 1 / L),
        word_mask=np.array(mask), region_counts=np.ones((1, K), dtype=int))
    return params, vocabulary


@pytest.mark.parametrize("mask", [[True] * 5, [True, True, False, True, True]])
def test_a_word_asked_alone_is_looked_up_by_every_name_that_holds_it_against_brute_force(mask) -> None:
    """p(m | "dining") ∝ Σ_l G_l π_{l,m} P(a token of concept l holds the word "dining"), the tokens
    enumerated one by one (the usable words only); "kitchen" is found by "kitchen" and "kitchen sink";
    a name of two tokens by its own two tokens said together, not by the words that hold them."""
    params, vocabulary = _tiny_home(mask)
    theta, g, pi = params.word_probabilities[0], params.concept_weights[0], params.region_weights[0]

    def brute(word: str) -> np.ndarray:
        holds = np.array([usable and word in token.split() for token, usable
                          in zip(vocabulary.words, mask, strict=True)])
        weights = np.zeros(pi.shape[1])
        for c in range(pi.shape[0]):
            said = sum(theta[c, j] for j in range(len(vocabulary)) if holds[j])  # one token at a time
            weights += g[c] * said * pi[c]
        return weights / weights.sum()

    for word in ("dining", "kitchen"):
        forms = position_prediction.query_forms(params, vocabulary, word)
        assert forms[0][0] == vocabulary.index(word)
        expected = {w for w, u in zip(vocabulary.words, mask, strict=True) if u and word in w.split()}
        assert {vocabulary.words[j] for j in forms[0]} == expected
        got = position_prediction.region_posterior_for_name(params, 0, vocabulary, word)
        assert_allclose(got, brute(word), rtol=1e-12)
    both = position_prediction.region_posterior_for_name(params, 0, vocabulary, "dining kitchen")
    joint_ = g[:, None] * (theta[:, 0] * theta[:, 3])[:, None] * pi
    assert position_prediction.query_forms(params, vocabulary, "dining kitchen") == [[0], [3]]
    # a longer name whose only known word is "dining" ("bunk" never said), or the words of a name
    # nobody said that the lexicon answers by them: the word alone
    assert position_prediction.query_forms(params, vocabulary, "bunk dining") == [[0]]
    assert position_prediction.query_forms(params, vocabulary, "dining", alone=False) == [[0]]
    alone = g[:, None] * theta[:, 0][:, None] * pi
    assert_allclose(position_prediction.region_posterior_for_name(params, 0, vocabulary, "bunk dining"),
                    alone.sum(axis=0) / alone.sum(), rtol=1e-12)
    assert_allclose(both, joint_.sum(axis=0) / joint_.sum(), rtol=1e-12)


@pytest.mark.parametrize("mask", [[True] * 5, [True, True, False, True, True],
                                  [False, True, True, True, True]])
def test_a_positions_name_is_how_query_name_understands_the_name_asked(mask) -> None:
    """``PositionPrediction.name`` is :func:`query_name` of the name asked: its usable tokens, each
    once, joined by " + " (not the learnt terms that hold a word asked alone); written out by hand."""
    params, vocabulary = _tiny_home(mask)
    usable = {w for w, u in zip(vocabulary.words, mask, strict=True) if u}
    known = {"dining": ["dining"], "kitchen": ["kitchen"], "dining kitchen": ["dining", "kitchen"],
             "kitchen dining kitchen": ["kitchen", "dining", "kitchen"], "bunk dining": ["dining"],
             "dining table": ["dining table"]}  # the known tokens of each name asked, in order
    for asked, tokens in known.items():
        expected = " + ".join(dict.fromkeys(t for t in tokens if t in usable))
        if not expected:
            with pytest.raises(UnknownNameError):
                position_prediction.query_name(vocabulary, params, asked)
            continue
        assert position_prediction.query_name(vocabulary, params, asked) == expected
        pred = position_prediction.predict_positions(params, 0, vocabulary, asked, n=2, rng=0, unheard=False)
        assert pred.name == expected


def test_a_rooms_own_names_against_brute_force() -> None:
    """p(w_1 w_2 | room k, l) of two tokens, each said through the names or the words of the place
    (shares a) and then φ_{c,k,w} ~ Beta(δ p_{c,l,w}, δ (1 − p_{c,l,w})) given the room's counts in
    that channel, and the regions' p(m | w) of three rooms in two regions, against the posterior
    means worked out by quadrature and summed by enumeration."""
    delta = 5.0
    a = [np.array([0.8, 0.3]), np.array([0.15, 0.6])]  # (n = 2,) per channel
    p = [np.array([[0.3, 0.6], [0.7, 0.2]]), np.array([[0.5, 0.25], [0.4, 0.8]])]  # (L = 2, n) per channel
    x = [np.array([[0.0, 0.0], [2.0, 1.0], [0.0, 3.0]]), np.array([[1.0, 0.0], [0.0, 0.0], [2.0, 1.0]])]
    tot = [np.array([0.0, 4.0, 5.0]), np.array([2.0, 0.0, 3.0])]
    channels = [(a[c], p[c], x[c], tot[c]) for c in range(2)]
    log_like = position_prediction.room_name_log_likelihood(channels, delta)
    expected = np.ones((3, 2))
    for k in range(3):
        for concept in range(2):
            for i in range(2):
                expected[k, concept] *= sum(a[c][i] * _beta_mean_by_quadrature(
                    delta * p[c][concept, i], delta * (1 - p[c][concept, i]), x[c][k, i],
                    tot[c][k] - x[c][k, i]) for c in range(2))
    assert_allclose(np.exp(log_like), expected, rtol=1e-4)  # the grid's error: ~1e-5
    # nothing said in a room: its concept's Σ_c a_c p_c; no concentration: every room its concept's
    said = sum(a[c][None, :] * p[c] for c in range(2)).prod(axis=1)
    quiet = [(a[c], p[c], np.zeros((1, 2)), np.zeros(1)) for c in range(2)]
    assert_allclose(np.exp(position_prediction.room_name_log_likelihood(quiet, delta))[0], said, rtol=1e-12)
    assert_allclose(np.exp(position_prediction.room_name_log_likelihood(channels, None)),
                    np.tile(said, (3, 1)), rtol=1e-12)
    # the regions, by enumeration over rooms and concepts: room 0 in region 0, rooms 1 and 2 in region 1
    n_k, p_l = np.array([30.0, 5.0, 2.0]), np.array([[0.9, 0.1], [0.2, 0.8], [0.5, 0.5]])
    region_of = [0, 1, 1]
    joint = np.zeros(2)
    for k in range(3):
        for concept in range(2):
            joint[region_of[k]] += n_k[k] * p_l[k, concept] * expected[k, concept]
    log_room = np.log(n_k) + np.log(np.exp(log_like + np.log(p_l)).sum(axis=1))
    assert_allclose(np.bincount(region_of, np.exp(log_room)) / np.exp(log_room).sum(), joint / joint.sum(),
                    rtol=1e-4)
    with pytest.raises(ConfigurationError, match="concentration"):
        position_prediction.room_name_log_likelihood(channels, 0.0)
    with pytest.raises(ConfigurationError, match="room's count"):
        position_prediction.room_name_log_likelihood([(a[0], p[0], x[0], np.zeros(3))], delta)


def test_a_name_said_in_one_room_is_found_there_though_no_concept_names_it() -> None:
    """A name said once in a small room as a word of the place, its concepts' θ^w and ψ near 0
    everywhere (the CI home's "pantry": ψ ≈ 5e-8 in every concept, the sampler's switch the place
    channel): the room that heard it is the answer, 10 times smaller than the others; without the
    rooms' own words it is not."""
    share = [np.array([0.34]), np.array([0.53])]
    probs = [np.zeros((2, 1)), np.full((2, 1), 5e-8)]
    said = [(np.zeros((3, 1)), np.zeros(3)),
            (np.array([[0.0], [0.0], [5000.0]]), np.array([0.0, 0.0, 5000.0]))]
    channels = [(share[c], probs[c], *said[c]) for c in range(2)]
    n_k, p_l = np.array([30.0, 30.0, 3.0]), np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    for delta, found in ((1e4, 2), (None, 0)):
        log_like = position_prediction.room_name_log_likelihood(channels, delta)
        weights = n_k * (p_l * np.exp(log_like)).sum(axis=1)
        assert int(np.argmax(weights)) == found


def test_a_name_taught_in_a_room_beats_an_untaught_room_of_its_concept() -> None:
    """A concept's name (θ^w 0.7) said 5 times in room 1 among 6 name tokens, room 0 of the same concept
    heard nothing and is larger (18 samples to 16): the taught room's own names make it the answer; with every
    room at its concept's θ^w the larger room would win."""
    channels = [(np.ones(1), np.array([[0.7]]), np.array([[0.0], [25000.0]]), np.array([0.0, 30000.0]))]
    n_k = np.array([18.0, 16.0])
    own = n_k * np.exp(position_prediction.room_name_log_likelihood(channels, 1e4)).ravel()
    flat = n_k * np.exp(position_prediction.room_name_log_likelihood(channels, None)).ravel()
    assert own[1] > own[0] and flat[0] > flat[1]


def test_a_rooms_words_are_the_expected_tokens_of_each_channel(joint, small_corpus) -> None:
    """The experiments' rooms count a sample's words as names and as words of the place by each token's
    switch probabilities given its concept (a joint fit keeps no switches): never more than were
    said, and a word the channels call background ("the") counts in neither."""
    from spco.model.word_channels import switch_probabilities

    e = 0  # an experienced home: its samples have sentences
    rooms = model_rooms(joint, e)
    data, state = joint.data_, joint.state_
    if state.channels is None:
        pytest.skip("the fit has no word channels")
    rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
    words = data.words[rows]
    said = rooms.names.toarray() + rooms.places.toarray()
    assert (said <= words.toarray() * (1 + 1e-12)).all() and said.sum() > 0
    p = switch_probabilities(words, np.asarray(data.homes)[rows], np.asarray(state.concepts)[rows],
                             state.log_theta_w, state.channels)
    assert_allclose(rooms.names.toarray()[words.nonzero()], words.data * p[:, 0])
    assert_allclose(rooms.places.toarray()[words.nonzero()], words.data * p[:, 1])


def _rooms_fields(rooms) -> list:
    return [rooms.regions, rooms.visual.toarray(), rooms.words.toarray(), rooms.concepts,
            None if rooms.names is None else rooms.names.toarray(),
            None if rooms.places is None else rooms.places.toarray(), rooms.concentration]


def _assert_same_rooms(a, b) -> None:
    for x, y in zip(_rooms_fields(a), _rooms_fields(b), strict=True):
        assert (x is None) == (y is None)
        if x is not None:
            assert_allclose(x, y, rtol=0, atol=0)


def _robot_rooms_before(home: kn.HomeModel):
    """home_rooms as it was before the one builder: the channels tested on the knowledge."""
    from spco.model.rooms import HomeRooms
    from spco.model.word_channels import channel_token_counts, name_tokens

    words, state = home.data.words, home.state
    if home.knowledge.channels is not None and state.switches is not None and words.nnz:
        words = name_tokens(words, state.switches)
    names = places = None
    if state.channels is not None:
        names, places = channel_token_counts(home.data.words, home.data.homes, state.concepts,
                                             state.log_theta_w, state.channels)
    return HomeRooms.of(state.regions, home.data.visual, words, state.concepts, names=names, places=places,
                        concentration=home.hyperparameters.delta_word)


def test_the_robot_and_the_experiments_build_their_rooms_with_one_builder(home: kn.HomeModel, joint,
                                                                          small_corpus, tmp_path) -> None:
    """home_rooms (the robot's: it tested the knowledge's channels) and model_rooms (the experiments':
    the state's) are sample_rooms of their data and state: a home's state holds the channels exactly
    when its knowledge does — adapted, loaded, taught, with and without the channels — so the rooms
    are those of before, field by field."""
    from spco.data.environment import Corpus
    from spco.data.synthetic import SyntheticConfig, generate_homes
    from spco.knowledge.queries import home_rooms
    from spco.model.rooms import sample_rooms

    corpus = generate_homes(3, seed=6, config=SyntheticConfig(n_features=64), new_homes=1,
                            specific_rooms=False)
    envs = list(corpus)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = kn.adapt(kn.fit_knowledge(Corpus(envs[:2]), n_iterations=4, random_state=0,
                                          model="spcotransfer"), envs[2], n_iterations=3, random_state=0)
    assert plain.knowledge.channels is None and home.knowledge.channels is not None
    for robot in (home, plain):
        taught = kn.teach(robot, {int(robot.ids[3]): "this is the pantry"}, random_state=0)
        robot.save(tmp_path / "home.spco", overwrite=True)
        for h in (robot, taught, kn.load_home_model(tmp_path / "home.spco")):
            assert (h.state.channels is None) == (h.knowledge.channels is None)
            assert (h.state.switches is None) == (h.knowledge.channels is None)
            _assert_same_rooms(home_rooms(h), _robot_rooms_before(h))
            _assert_same_rooms(home_rooms(h), sample_rooms(h.data, h.state, h.hyperparameters.delta_word))
    # the experiments' joint fit: the rooms model_rooms built before (the channels tested on the state)
    from spco.model.rooms import HomeRooms
    from spco.model.word_channels import channel_token_counts, name_tokens

    data, state = joint.data_, joint.state_
    for e in range(len(small_corpus)):
        rows = slice(int(data.offsets[e]), int(data.offsets[e + 1]))
        words = data.words
        if state.channels is not None and state.switches is not None and words.nnz:
            words = name_tokens(words, state.switches)
        names = places = None
        if state.channels is not None:
            names, places = channel_token_counts(data.words[rows], np.asarray(data.homes)[rows],
                                                 np.asarray(state.concepts)[rows], state.log_theta_w,
                                                 state.channels)
        before = HomeRooms.of(np.asarray(state.regions)[rows], data.visual[rows], words[rows],
                              np.asarray(state.concepts)[rows], names=names, places=places,
                              concentration=float(joint.hyperparameters_.delta_word))
        _assert_same_rooms(model_rooms(joint, e), before)


def test_where_keeps_what_does_not_depend_on_the_name_and_answers_the_same(home: kn.HomeModel) -> None:
    """The rooms' concepts, membership and said counts are worked out once per rooms and parameters
    object (the part of `where` that is the same for every name); the answers are those of fresh rooms,
    and new parameters are not answered from the old ones' rooms."""
    from dataclasses import replace

    from scipy.special import logsumexp

    from spco.knowledge.queries import answer_inputs, home_rooms

    params, rooms = answer_inputs(home)
    w = home.hyperparameters.view_weight()
    for name in home.known_names:
        warm = position_prediction.region_posterior_for_name(params, 0, home.vocabulary, name, rooms=rooms,
                                                             view_counts=w, lookup=home.parameters.word_mask)
        fresh = position_prediction.region_posterior_for_name(params, 0, home.vocabulary, name,
                                                              rooms=home_rooms(home), view_counts=w,
                                                              lookup=home.parameters.word_mask)
        assert_allclose(warm, fresh, rtol=0, atol=1e-15)
    K = int(np.shape(params.region_means)[1])
    assert rooms.membership(K) is rooms.membership(K)
    # other parameters (G_0 changed): worked out again, not read from the rooms' memory
    other = replace(params, global_concept_weights=np.roll(np.asarray(params.global_concept_weights), 1))
    name = home.known_names[0]
    kept = position_prediction.region_posterior_for_name(other, 0, home.vocabulary, name, rooms=rooms,
                                                         view_counts=w, lookup=home.parameters.word_mask)
    again = position_prediction.region_posterior_for_name(other, 0, home.vocabulary, name,
                                                          rooms=home_rooms(home), view_counts=w,
                                                          lookup=home.parameters.word_mask)
    base = position_prediction.region_posterior_for_name(params, 0, home.vocabulary, name, rooms=rooms,
                                                         view_counts=w, lookup=home.parameters.word_mask)
    assert not np.allclose(kept, base)  # (G_0 moved the answer: a stale memory would be seen)
    assert_allclose(kept, again, rtol=0, atol=1e-15)
    # the log-sum-exp `where` uses, against scipy's, with rows of -inf and of huge magnitudes
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 5)) * np.array([[1.0], [1e3], [1e300], [1.0], [1.0], [1.0]])
    a[3] = -np.inf
    a[4, :2] = -np.inf
    with np.errstate(invalid="ignore"):
        assert_allclose(position_prediction._log_sum_exp(a, axis=1), logsumexp(a, axis=1), rtol=1e-14)
        assert_allclose(position_prediction._log_sum_exp(a[:, 0], axis=0), logsumexp(a[:, 0]), rtol=1e-14)


def test_the_librarys_predictions_are_what_the_robot_answers_and_the_experiments_score(joint,
                                                                                      small_corpus) -> None:
    """SpCoTransfer.predict_names and predict_positions answer with the robot's predictor (the answer's
    parameters, the room account, the robot's weighting; unsure below the one threshold), the one the
    experiments score (before: the bare parameters, the MI weighting, no rooms)."""
    from spco.model.confidence import UNSURE_BELOW, answer_names, answer_weighting
    from spco.model.prediction import predict_names

    e = len(small_corpus) - 1
    env = small_corpus[e]
    rows = np.flatnonzero(env.is_test)
    params, rooms, weighting = joint.answer_inputs(e)
    assert weighting == answer_weighting(joint.variant, joint.prune_words) == "none"
    assert joint.answer_inputs(env.name)[1] is rooms  # worked out once per fit
    w = joint.settings_.view_counts
    pred = joint.predict_names(env.name, env.positions[rows], env.visual[rows], top_k=3)
    robot = answer_names(model_answer_parameters(joint, e), e, joint.vocabulary_, env.positions[rows],
                         env.visual[rows], view_counts=w, weighting="none", rooms=model_rooms(joint, e),
                         name_prior=joint.hyperparameters_.name_prior, settings=AnswerSettings())
    assert pred.unsure_below == UNSURE_BELOW
    assert_allclose(pred.word_probabilities, robot.word_probabilities, rtol=0, atol=1e-15)
    assert (pred.words == robot.words).all()
    bare = predict_names(joint.parameters_, e, joint.vocabulary_,
                                                         env.positions[rows], env.visual[rows], view_counts=w)
    assert not np.allclose(bare.word_probabilities, pred.word_probabilities)  # (what it answered before)
    scores = evaluate_home(joint.parameters_, e, env, joint.vocabulary_, rng=0, view_counts=w,
                           weighting=weighting, answer_params=params, answer_rooms=rooms)
    assert scores.position_predictions
    for place, scored in scores.position_predictions.items():
        mine = joint.predict_positions(e, scored.name, n=3, random_state=0, mode="argmax")
        assert_allclose(mine.region_probabilities, scored.region_probabilities, rtol=0, atol=0, err_msg=place)
