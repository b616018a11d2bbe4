"""The warm start of a fit that learns its words with the word channels (issue 28, class c: concepts
that hold two rooms): the start's sweeps weigh a word token as the chain does, the words the channels'
evidence calls objects and WordNet calls things mark no place
(:func:`spco.model.word_channels.warm_start_settings`), and a home taught less than the others holds
the samples of its own names in their concepts through those sweeps
(:func:`spco.model.shard_init.initialise`). The start is not part of either target: the chain's
conditionals are those of ``tests/test_word_channels.py`` and ``tests/test_power_target.py``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from spco.data.lexicon import lexicon
from spco.data.synthetic import SyntheticConfig, generate_homes
from spco.engines import LocalEngine
from spco.errors import ConfigurationError
from spco.model import assignments
from spco.model.gibbs import GibbsState, PreparedData
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.shard_init import ShardInitialisation
from spco.model.sources import PreparedHomes
from spco.model.state import SamplerSettings
from spco.model.transfer import SpatialConceptModel
from spco.model.unheard import OBJECT_BELOW
from spco.model.word_channels import WordChannels, token_weight, warm_start_settings


class _Words:
    def __init__(self, words: list[str]) -> None:
        self.words = words

    def __len__(self) -> int:
        return len(self.words)


class _Rooms:
    """A lexicon that knows which of its words can be a room and which are things."""

    def __init__(self, rooms: set[str], things: set[str] = frozenset()) -> None:
        self.rooms = rooms
        self.things = things

    def room_share(self, word: str) -> float:
        return 1.0 if word in self.rooms else 0.0

    def is_thing(self, word: str) -> bool:
        return word in self.things


def test_the_warm_start_settings_weigh_a_token_and_leave_out_the_objects() -> None:
    nu = np.array([0.8, 0.05, 0.3, 0.1, 0.6, 0.05])  # a name, an object, a weak name, an object, a name,
    content = np.array([0.95, 0.95, 0.9, 0.95, 0.5, 0.95])  # and a room the sentences call an object
    words = _Words(["kitchen", "table", "nook", "sofa", "den", "toilet"])
    settings = SamplerSettings.create("exact", prune=True, view_counts=16.0)
    assert settings.word_weight == 1.0 and settings.start_not_names == ()  # S^w: as before
    hyper = TransferHyperparameters(n_concepts=4, evidence_weight=1.0, word_counts=16.0, warm_start="words")
    # the default start ("names"): the settings as they are
    assert warm_start_settings(settings, replace(hyper, warm_start="names"), (nu, content), words, 5000,
                               _Rooms({"toilet"})) is settings
    out = warm_start_settings(settings, hyper, (nu, content), words, 5000, _Rooms({"toilet"}))
    assert out.word_weight == pytest.approx(token_weight(16.0, 5000)) == pytest.approx(16 / 5000)
    prior = WordChannels.initial(nu, 4, 1.0, content).name_prior()
    low = tuple(int(k) for k in np.flatnonzero(prior < OBJECT_BELOW))
    assert low == (1, 3, 5)
    assert out.start_not_names == (1, 3)  # "toilet" can be a room: it keeps its place
    # the rest of the settings as they were; S^w per token when the word weight is none
    assert out.view_counts == 16.0 and out.variant == "exact"
    assert warm_start_settings(settings, replace(hyper, word_counts=None), (nu, content), words, 5000,
                               _Rooms(set())).word_weight == 1.0
    with pytest.raises(ConfigurationError, match="warm_start"):
        TransferHyperparameters(warm_start="sweeps")
    assert TransferHyperparameters().with_settings(["warm_start=words"]).warm_start == "words"
    assert TransferHyperparameters().warm_start == "things"  # the default (branch things16)


def test_the_objects_start_is_no_option_and_a_file_that_says_it_reads_as_things() -> None:
    """start14's ``"objects"`` is gone: asking for it (``--set``, the constructor) is an error naming the
    field and the options; a file that says it loads, as ``"things"``, with a FutureWarning naming it."""
    with pytest.raises(ConfigurationError, match=r"warm_start.*'names', 'words', 'things'"):
        TransferHyperparameters(warm_start="objects")  # type: ignore[arg-type]
    with pytest.raises(ConfigurationError, match="warm_start"):
        TransferHyperparameters().with_settings(["warm_start=objects"])
    data = TransferHyperparameters(warm_start="names").to_dict()
    data["warm_start"] = "objects"
    with pytest.warns(FutureWarning, match="warm_start='objects' is no longer an option: read as 'things'"):
        hyper = TransferHyperparameters.from_dict(data)
    assert hyper == TransferHyperparameters(warm_start="things")


def test_the_things_start_leaves_out_only_the_objects_wordnet_calls_things() -> None:
    """``warm_start="things"``: of the words the evidence calls objects (name prior below
    OBJECT_BELOW), only those whose head word the lexicon calls a thing mark no place — brute force
    over the words — a word the lexicon does not know stays a name (the "objects" start left it out);
    the token weight stays as given."""
    nu = np.array([0.8, 0.05, 0.3, 0.1, 0.6, 0.05, 0.05, 0.05])
    content = np.array([0.95, 0.95, 0.9, 0.95, 0.5, 0.95, 0.95, 0.95])
    words = _Words(["kitchen", "table", "fridge", "sofa", "den", "toilet", "dormitorio", "hanako's towel"])
    lexicon_ = _Rooms({"toilet", "kitchen"}, {"sofa", "towel", "fridge", "table"})
    settings = SamplerSettings.create("exact", prune=True, view_counts=16.0)
    hyper = TransferHyperparameters(n_concepts=4, evidence_weight=1.0, word_counts=16.0, warm_start="things")
    out = warm_start_settings(settings, hyper, (nu, content), words, 5000, lexicon_)
    prior = WordChannels.initial(nu, 4, 1.0, content).name_prior()
    expected = tuple(k for k in range(len(words)) if prior[k] < OBJECT_BELOW
                     and words.words[k].split()[-1] in lexicon_.things)
    assert out.start_not_names == expected == (1, 3, 7)  # "fridge" has a name prior: it stays
    assert out == replace(settings, start_not_names=expected)  # S^w per token, as given
    absent = warm_start_settings(settings, replace(hyper, warm_start="words"), (nu, content), words,
                                 5000, lexicon_)
    assert absent.start_not_names == (1, 3, 6, 7)  # the absence of a room sense leaves "dormitorio" out
    assert TransferHyperparameters().with_settings(["warm_start=names"]).warm_start == "names"
    names = TransferHyperparameters(warm_start="names")
    assert names.with_settings(["warm_start=things"]).warm_start == "things"


@pytest.mark.skipif(lexicon() is None, reason="WordNet is not installed")
def test_wordnet_calls_fridge_kettle_towel_things_but_not_unknown_words_or_dining() -> None:
    """With WordNet, positive evidence of a thing: "fridge", "kettle", "towel", "bed" are things; a word
    WordNet does not know ("dormitorio"), "dining" and "living" (mostly not nouns), rooms ("toilet",
    "bathroom", "kitchen"), "laundry" (often a room), "table" (mostly a table of data) and the things
    WordNet also calls by a room's word ("tub" and "bathtub": bathtub.n.01 is also "bath"; "sofa":
    "lounge") are not; the things start leaves out exactly the things."""
    lex = lexicon()
    assert lex is not None
    things = ["fridge", "kettle", "towel", "bed"]
    not_things = ["dormitorio", "dining", "living", "toilet", "bathroom", "kitchen", "laundry", "table",
                  "comedor", "wc", "tub", "bathtub", "sofa"]
    assert all(lex.is_thing(w) for w in things)
    assert not any(lex.is_thing(w) for w in not_things)
    assert lex.thing_share("sofa") == 1.0 and np.isnan(lex.thing_share("dormitorio"))
    words = things + not_things
    nu, content = np.full(len(words), 0.05), np.full(len(words), 0.95)
    hyper = TransferHyperparameters(n_concepts=4, evidence_weight=1.0, word_counts=16.0, warm_start="things")
    out = warm_start_settings(SamplerSettings.create("exact", prune=True), hyper, (nu, content),
                              _Words(words), 5000)
    assert [words[k] for k in out.start_not_names] == things
    absent = warm_start_settings(SamplerSettings.create("exact", prune=True),
                                 replace(hyper, warm_start="words"), (nu, content), _Words(words), 5000)
    assert {"dormitorio", "dining", "living"} <= {words[k] for k in absent.start_not_names}


@pytest.mark.skipif(lexicon() is None, reason="WordNet is not installed")
def test_a_things_room_namesakes_are_the_words_of_its_senses_with_a_room_sense() -> None:
    """``Lexicon.room_namesakes`` against brute force over WordNet: the lemmas of the word's noun senses,
    other than the word and its base form, whose own senses include a room (``room_share`` > 0); a thing
    with such a namesake is no thing for ``is_thing``, whatever else WordNet says of it."""
    lex = lexicon()
    assert lex is not None
    assert lex.room_namesakes("tub") == lex.room_namesakes("bathtub") == ["bath"]
    assert lex.room_namesakes("fridge") == lex.room_namesakes("towels") == []
    for word in ("tub", "couch", "wardrobe", "kettle", "stool", "fridge", "towels", "bed"):
        forms = {word, lex._wn.morphy(word, "n")}
        brute = []
        for synset in lex.synsets(word, pos="n"):
            for name in synset.lemma_names():
                text = name.lower().replace("_", " ")
                if name.lower() not in forms and text not in brute and lex.room_share(text) > 0:
                    brute.append(text)
        assert lex.room_namesakes(word) == brute, word
        if brute:
            assert not lex.is_thing(word)


def test_the_start_is_always_written_and_a_file_without_it_means_names() -> None:
    """``to_dict`` writes ``warm_start`` whatever it is (``"names"`` too: it is no longer the default),
    and ``from_dict`` reads a dictionary without it as ``"names"`` (the files written before things16,
    whose default was ``"names"``), not as the default ``"things"``."""
    for start in ("names", "words", "things"):
        hyper = TransferHyperparameters(warm_start=start)  # type: ignore[arg-type]
        data = hyper.to_dict()
        assert data["warm_start"] == start
        assert TransferHyperparameters.from_dict(data) == hyper
    old = TransferHyperparameters().to_dict()
    del old["warm_start"]
    assert TransferHyperparameters.from_dict(old).warm_start == "names"
    assert TransferHyperparameters.from_dict(old) == TransferHyperparameters(warm_start="names")


def test_the_start_round_trips_through_the_knowledge_and_home_files(tmp_path) -> None:
    """``spco fit`` keeps the start in the knowledge file (the default ``"things"``, and
    ``--set warm_start=names``), ``spco adapt`` in the home file; a file whose header has no
    ``warm_start`` reads as ``"names"``."""
    import json

    from conftest import fit_and_adapt, synthetic_home_folders

    from spco import knowledge as kn

    for given, start in (((), "things"), (("--set", "warm_start=names"), "names")):
        folders = synthetic_home_folders(tmp_path / start, 4, seed=3, n_features=64)
        knowledge_file, home_file, _ = fit_and_adapt(
            folders, ["--iterations", 2, "--seed", 0, *given], ["--iterations", 2])
        assert kn.load_knowledge(knowledge_file).hyperparameters.warm_start == start
        assert kn.load_home_model(home_file).hyperparameters.warm_start == start
        with np.load(knowledge_file, allow_pickle=False) as archive:
            header = json.loads(archive["header"].tobytes().decode("utf-8"))
        assert header["hyperparameters"]["warm_start"] == start
        del header["hyperparameters"]["warm_start"]
        assert TransferHyperparameters.from_dict(header["hyperparameters"]).warm_start == "names"


@pytest.mark.skipif(lexicon() is None, reason="WordNet is not installed")
def test_wordnet_keeps_the_rooms_and_leaves_out_the_furniture() -> None:
    """With WordNet: "toilet" and "bathroom" (names the free-form homes' sentences make look like
    objects) can be rooms; "table", "sofa", "bed" cannot."""
    words = ["toilet", "bathroom", "table", "sofa", "bed"]
    nu, content = np.full(5, 0.05), np.full(5, 0.95)
    hyper = TransferHyperparameters(n_concepts=4, evidence_weight=1.0, word_counts=16.0, warm_start="words")
    out = warm_start_settings(SamplerSettings.create("exact", prune=True), hyper, (nu, content),
                              _Words(words), 5000)
    assert [words[k] for k in out.start_not_names] == ["table", "sofa", "bed"]


def _one_home(words: sp.csr_array, n_concepts: int,
              rng: np.random.Generator) -> tuple[PreparedData, GibbsState]:
    n = words.shape[0]
    data = PreparedData(positions=rng.normal(size=(n, 4)), homes=np.zeros(n, dtype=np.int64),
                        visual=sp.csr_array(rng.integers(0, 5, (n, 3))), words=words, n_homes=1,
                        offsets=np.array([0, n]), position_scale=1.0, map_centres=np.zeros((1, 4)))
    log_theta_v = np.log(rng.dirichlet(np.ones(3), (1, n_concepts)))
    log_theta_w = np.log(rng.dirichlet(np.ones(words.shape[1]), (1, n_concepts)))
    state = GibbsState(concepts=np.zeros(n, dtype=np.int64), regions=np.zeros(n, dtype=np.int64),
                       log_g=np.zeros((1, n_concepts)), log_g0=np.zeros(n_concepts),
                       log_pi=np.zeros((1, n_concepts, 1)), means=np.zeros((1, 1, 4)),
                       covariances=np.tile(np.eye(4), (1, 1, 1, 1)), log_theta_v=log_theta_v,
                       log_theta_w=log_theta_w, log_phi_v=log_theta_v[0], log_phi_w=log_theta_w[0],
                       word_mask=np.ones(words.shape[1], dtype=bool))
    return data, state


def test_the_start_weighs_the_words_by_the_word_weight() -> None:
    """Without channels (the start's sweeps) a sample's word log-likelihood under each concept is
    ``word_weight`` times that of S^w counts per token; the view's is unchanged."""
    rng = np.random.default_rng(3)
    words = sp.csr_array(rng.integers(0, 3, (6, 5)) * 5000)
    data, state = _one_home(words, 3, rng)
    full = assignments.concept_loglik(data, state, 16.0)
    views = assignments.concept_loglik(data, state, 16.0, 0.0)  # the words weigh nothing: the views alone
    weighed = assignments.concept_loglik(data, state, 16.0, 16 / 5000)
    assert np.allclose(weighed - views, (full - views) * 16 / 5000)
    assert not np.allclose(full, views)  # (the words do count)


def _partly_taught_corpus():
    """5 synthetic homes; the last (with the home-specific bedrooms) keeps 2 of every 5 sentences."""
    corpus = generate_homes(5, seed=4, config=SyntheticConfig(n_features=64, n_train=12))
    last = corpus[-1]
    kept = [s if i % 5 < 2 else None for i, s in enumerate(last.sentences)]
    homes = [*corpus[:-1], last.with_sentences(kept)]
    return type(corpus)(homes)


@pytest.mark.parametrize("word_weight", [16 / 5000, 1.0])
def test_a_home_taught_less_holds_its_own_names_through_the_start(monkeypatch, word_weight: float) -> None:
    """With a word weight below S^w the samples of the partly taught home that stand for a name said
    in no fully taught home (brute force over the homes' sentences) keep their starting concepts
    through every independent sweep, and that home's words weigh S^w there; the fully taught homes'
    weigh W^w and their samples move. At S^w (weight 1) nothing is held."""
    corpus = _partly_taught_corpus()
    model = SpatialConceptModel(variant="exact", random_state=0, prune_words=True)
    hyper, settings = model.checked_hyperparameters(), model.sampler_settings()
    settings = replace(settings, word_weight=word_weight)
    data = PreparedData.from_corpus(corpus, 1.0)
    last = data.n_homes - 1
    rows = slice(data.offsets[last], data.offsets[last + 1])
    seen: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []  # the last home's sweeps
    others_moved: list[bool] = []
    local_step = ShardInitialisation.init_local_step

    def spy(self) -> None:
        before = self.state.concepts.copy()
        local_step(self)
        held = getattr(self, "_held", np.zeros(0, dtype=np.int64))
        weight = np.asarray(getattr(self, "_word_weight", self.settings.word_weight))
        if np.array_equal(self.data.positions, data.positions[rows]):
            seen.append((held, before, self.state.concepts.copy(), self._names.copy()))
            assert np.all(weight == 1.0)  # the partly taught home's words weigh S^w in the start
        else:
            assert held.size == 0 and np.all(weight == word_weight)  # a fully taught home: W^w, nothing held
            others_moved.append(bool((before != self.state.concepts).any()))

    monkeypatch.setattr(ShardInitialisation, "init_local_step", spy)
    run = LocalEngine(1).start_source(PreparedHomes(data, len(corpus.vocabulary)), hyper, settings,
                                      np.random.default_rng(0))
    run.close()
    assert seen and any(others_moved)  # (the sweeps do draw the samples)
    if word_weight == 1.0:
        assert all(h.size == 0 for h, *_ in seen)
        return
    # brute force: the words said in the fully taught homes; the last home's samples of its own names
    names = seen[0][3]
    said_elsewhere = set(np.unique(data.words[np.arange(data.offsets[last])].indices).tolist())
    expected = [i for i in range(names.size) if names[i] >= 0 and int(names[i]) not in said_elsewhere]
    assert expected
    words = {corpus.vocabulary.words[int(names[i])] for i in expected}
    assert all("'s" in w for w in words), words  # the home-specific rooms' names
    for held, before, after, _ in seen:
        assert held.tolist() == expected
        assert np.array_equal(before[held], after[held])
