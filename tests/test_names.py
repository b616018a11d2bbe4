"""Which words are names (:mod:`spco.model.name_evidence`) and names never heard (:mod:`spco.model.unheard`,
:mod:`spco.data.lexicon`): docs/model.md, "What counts as a name" and "Names never heard"."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from spco.data.function_words import DETERMINERS, PREPOSITIONS
from spco.data.language import Vocabulary
from spco.data.lexicon import LexiconMatch, lexicon, lexicon_unavailable_reason
from spco.errors import ConfigurationError
from spco.model.hyperparameters import TransferHyperparameters
from spco.model.name_evidence import (
    FEATURES,
    frame_features,
    holds_determiner,
    lexical_features,
    name_prior,
    within_concepts,
)
from spco.model.parameters import ConceptParameters
from spco.model.position_prediction import predict_positions
from spco.model.prediction import UnknownNameError, predict_names
from spco.model.unheard import resolve_name

# ------------------------------------------------------------------------------ sentence frames


def _frames(sentences: list[str]) -> tuple[Vocabulary, dict[str, np.ndarray]]:
    vocab = Vocabulary.from_sentences(sentences, learn=False)
    f = frame_features(vocab, sentences)
    return vocab, {w: f[k] for k, w in enumerate(vocab.words)}


def test_frames_of_hand_made_sentences() -> None:
    _, f = _frames(["this is the kitchen", "the table is here", "we eat on the table", "i'm home",
                    "kitchen"])
    det, frame, prep, pron, start, alone = range(6)
    assert f["kitchen"][det] == 0.5 and f["kitchen"][frame] == 1.0 and f["kitchen"][alone] == 0.5
    assert f["table"][det] == 1.0 and f["table"][prep] == 0.5  # "the table is here", "on the table"
    assert f["table"][frame] == 0.5  # "… is here" frames it, "on the table" does not
    assert f["home"][pron] == 1.0 and f["home"][det] == 0.0  # "i'm home": a greeting
    assert f["this"][start] == 1.0


def test_a_possessive_term_is_read_as_its_head_after_a_determiner() -> None:
    """"this is emma's room" with "emma's room" one token frames it as "room" is framed when the
    possessive is a token of its own: after a determiner, in a naming frame. So do "mum and dad's
    room", "kids' room" and "my room"; "living room", "over here" and a lone "emma's" hold none."""
    assert all(map(holds_determiner, ["emma's room", "mum and dad's room", "kids' room", "my room",
                                      "our spare room"]))
    assert not any(map(holds_determiner, ["living room", "over here", "emma's", "room", "the room's"]))
    said = ["this is emma's room", "we call it mum and dad's room", "my room is where i sleep"]
    terms = Vocabulary(("emma's room", "mum and dad's room", "my room", "this", "is", "we", "call", "it",
                        "where", "i", "sleep"))
    apart = Vocabulary(("emma's", "room", "mum", "and", "dad's", "my", "this", "is", "we", "call", "it",
                        "where", "i", "sleep"))
    joined = frame_features(terms, said)
    split = frame_features(apart, said)
    room = split[apart.index("room")]  # "room" after "emma's", "dad's" and "my"
    det, frame, prep, pron, start, alone = range(6)
    for term in ("emma's room", "mum and dad's room", "my room"):
        f = joined[terms.index(term)]
        assert f[det] == 1.0 and f[frame] == 1.0 and f[prep] == 0.0 and f[pron] == 0.0 and f[alone] == 0.0
    # each term framed as "room" is in its sentence; the three together as "room" over the three
    together = joined[[terms.index(t) for t in ("emma's room", "mum and dad's room", "my room")]].mean(axis=0)
    shares = [det, frame, prep, pron, alone]
    np.testing.assert_allclose(together[shares], room[shares])
    # the sentence-start share counts the term's own position ("my room" opens its sentence)
    assert joined[terms.index("my room")][start] == 1.0 and joined[terms.index("emma's room")][start] == 0.0


@given(st.lists(st.lists(st.sampled_from(["the", "my", "on", "kitchen", "table", "is", "here", "we"]),
                         min_size=1, max_size=6), min_size=1, max_size=8))
def test_frame_shares_match_a_brute_force_count(sentences: list[list[str]]) -> None:
    texts = [" ".join(s) for s in sentences]
    vocab, f = _frames(texts)
    for word in vocab.words:
        uses = [(s, i) for s in sentences for i, t in enumerate(s) if t == word]
        det = np.mean([i > 0 and (s[i - 1] in DETERMINERS) for s, i in uses])
        prep = np.mean([(i > 0 and s[i - 1] in PREPOSITIONS)
                        or (i > 1 and s[i - 1] in DETERMINERS and s[i - 2] in PREPOSITIONS) for s, i in uses])
        assert f[word][0] == pytest.approx(det) and f[word][2] == pytest.approx(prep)
        assert np.all((f[word] >= 0) & (f[word] <= 1))


@given(st.integers(1, 4), st.integers(2, 6), st.integers(0, 2**31 - 1))
def test_reweighting_keeps_each_place_s_weight_and_orders_its_words_by_the_prior(
        n_concepts: int, n_words: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    weighted = rng.random((n_concepts, n_words)) * (rng.random((n_concepts, n_words)) > 0.3)
    prior = rng.uniform(0.01, 0.99, n_words)
    out = within_concepts(weighted, prior)
    assert np.allclose(out.sum(axis=1), weighted.sum(axis=1))
    assert np.all(out[weighted == 0] == 0)
    for row_in, row_out in zip(weighted, out, strict=True):
        for a, b in itertools.combinations(np.flatnonzero(row_in), 2):
            # the ratio of two words of one place changes by the ratio of their priors, exactly
            assert row_out[a] * row_in[b] * prior[b] == pytest.approx(row_out[b] * row_in[a] * prior[a])


# ------------------------------------------------------------------------------ WordNet


def test_wordnet_tells_places_from_furniture_objects_and_acts(wordnet) -> None:
    for place in ("kitchen", "bedroom", "restroom", "living room", "foyer", "hallway"):
        assert wordnet.place_share(place) >= 0.99, place
    for thing in ("table", "sofa", "towel", "fridge", "dining", "sleep"):
        assert wordnet.place_share(thing) == 0.0, thing
    assert wordnet.noun_share("greet") == 0.0 and wordnet.noun_share("kitchen") == 1.0
    # said of a place, a word names something there: its abstract senses (study as learning, a report)
    # do not dilute its place senses (the room), and a word whose noun senses are all abstract has none
    assert wordnet.place_share("study") > 0.5 and wordnet.place_share("music") == 0.0
    assert wordnet.place_share("desk") == 0.0 and wordnet.place_share("bed") < 0.3
    assert np.isnan(wordnet.noun_share("genkan"))  # unknown to WordNet: neutral
    feats = lexical_features(["kitchen", "emma's room", "the", "genkan"], wordnet)
    assert feats[1, 2] == pytest.approx(wordnet.place_share("room"))  # a term: its head word
    assert feats[2, 3] == 1.0 and feats[3, 0] == 0.0


def test_the_prior_prefers_a_place_s_name_to_what_is_said_there(wordnet) -> None:
    sentences = ["this is the dining room", "the dining room is here", "our dining room", "dining room",
                 "we eat on the table", "the table is big", "put it on the table", "i sleep here",
                 "hi i'm home", "the bath is to your left"]
    vocab = Vocabulary.from_sentences(sentences)
    prior = dict(zip(vocab.words, name_prior(vocab, sentences, wordnet), strict=True))
    assert prior["dining room"] > 3 * max(prior["table"], prior["sleep"], prior["home"], prior["left"])
    assert prior["dining room"] > 10 * max(prior["our"], prior["i"], prior["we"])
    assert len(FEATURES) == 11


def _two_place_params(theta: np.ndarray) -> ConceptParameters:
    """One home, two concepts at two regions (x = 0 and x = 5) saying ``theta`` (2, V)."""
    theta = np.asarray(theta, dtype=float)[None] + 1e-6
    theta /= theta.sum(axis=2, keepdims=True)
    return ConceptParameters(
        concept_weights=np.array([[0.5, 0.5]]), region_weights=np.array([[[0.99, 0.01], [0.01, 0.99]]]),
        region_means=np.array([[[0.0, 0.0, 0.0, 1.0], [5.0, 0.0, 0.0, 1.0]]]),
        region_covariances=np.tile(np.eye(4) * 0.1, (1, 2, 1, 1)),
        word_probabilities=theta, visual_probabilities=np.full((1, 2, 3), 1 / 3),
        shared_word_probabilities=theta[0], shared_visual_probabilities=np.full((2, 3), 1 / 3),
        global_concept_weights=np.array([0.5, 0.5]), word_mask=np.ones(theta.shape[2], dtype=bool),
        region_counts=np.array([[10, 10]]), concept_counts=np.array([[10.0, 10.0]]))


def _two_place_params_with_place_words(theta: np.ndarray, psi: np.ndarray,
                                      prior: np.ndarray) -> ConceptParameters:
    """:func:`_two_place_params` with the word channels: the words said at each place ``psi`` (2, V)
    and the switch's prior, name ``prior`` (V,) and place the rest."""
    prior = np.asarray(prior, dtype=float)
    return replace(_two_place_params(theta), name_prior=prior, place_word_probabilities=psi,
                   word_channel_prior=np.column_stack([prior, 1.0 - prior, np.zeros(prior.size)]))


def test_a_furniture_word_said_more_often_does_not_name_the_place(wordnet) -> None:
    # the dining area is called "dining room" in 2 sentences of 5 and "the table" is said in 3: the
    # model's θ^w gives "table" the most at the dining area (concept 0), the kitchen (concept 1) says
    # "kitchen"; the naming rule keeps both words (both are said at one place)
    sentences = (["this is the dining room", "the dining room is here", "we eat at the table",
                  "the table is here", "put it on the table", "this is the kitchen", "the kitchen is here"])
    words = ("this", "is", "the", "dining room", "table", "here", "kitchen")
    vocab = Vocabulary(words)
    theta = np.array([[0.1, 0.1, 0.2, 0.2, 0.3, 0.1, 0.0],
                      [0.1, 0.1, 0.2, 0.0, 0.0, 0.1, 0.5]])
    params = _two_place_params(theta)
    dining, kitchen = np.array([[0.0, 0.0, 0.0, 1.0]]), np.array([[5.0, 0.0, 0.0, 1.0]])
    assert predict_names(params, 0, vocab, dining, None, use_vision=False).best == ["table"]  # before
    with_prior = replace(params, name_prior=name_prior(vocab, sentences, wordnet))
    # the prior alone changes nothing: the ordering is opt-in (name_prior="wordnet")
    default = predict_names(with_prior, 0, vocab, dining, None, use_vision=False)
    assert default.best == ["table"]
    np.testing.assert_array_equal(default.scores, predict_names(params, 0, vocab, dining, None,
                                                                use_vision=False).scores)
    opt_in = {"use_vision": False, "name_prior": "wordnet"}
    assert predict_names(with_prior, 0, vocab, dining, None, **opt_in).best == ["dining room"]
    # the other place keeps its name: the evidence moves no weight between places
    assert predict_names(with_prior, 0, vocab, kitchen, None, **opt_in).best == ["kitchen"]
    # without a prior (a model without the naming rule) the opt-in keeps the MI order
    assert predict_names(params, 0, vocab, dining, None, **opt_in).best == ["table"]
    with pytest.raises(ConfigurationError, match="name_prior must be one of 'off', 'wordnet'"):
        predict_names(with_prior, 0, vocab, dining, None, name_prior="on")  # type: ignore[arg-type]


def test_the_name_prior_setting_is_off_by_default_and_written_only_when_on() -> None:
    assert TransferHyperparameters().name_prior == "off"
    assert "name_prior" not in TransferHyperparameters().to_dict()  # older files and identities unchanged
    on = TransferHyperparameters(name_prior="wordnet")
    assert on.to_dict()["name_prior"] == "wordnet" and TransferHyperparameters.from_dict(on.to_dict()) == on
    assert TransferHyperparameters.from_dict(TransferHyperparameters().to_dict()) == TransferHyperparameters()
    with pytest.raises(ConfigurationError, match="name_prior must be one of"):
        TransferHyperparameters(name_prior="WordNet")  # type: ignore[arg-type]


# ------------------------------------------------------------------------------ names never heard


def _toilet_kitchen() -> tuple[ConceptParameters, Vocabulary]:
    """Concept 0 at x = 0 says "toilet", concept 1 at x = 5 "kitchen"."""
    theta = np.array([[0.7, 0.3, 0.0], [0.0, 0.3, 0.7]])
    return _two_place_params(theta), Vocabulary(("toilet", "is", "kitchen"))


def test_where_finds_a_name_nobody_said_and_says_which_name_it_used(wordnet) -> None:
    params, vocab = _toilet_kitchen()
    for asked in ("restroom", "Powder Room", "loo", "lavatory"):
        pred = predict_positions(params, 0, vocab, asked, n=5, rng=0)
        assert (pred.asked, pred.name) == (asked.lower(), "toilet"), (asked, pred.asked, pred.name, pred.via)
        assert pred.region == 0 and np.all(np.abs(pred.samples[:, 0]) < 2.0)
    assert predict_positions(params, 0, vocab, "kitchenette", n=3, rng=0).name == "kitchen"
    said = predict_positions(params, 0, vocab, "toilet", n=3, rng=0)
    assert said.asked is None and said.via is None
    with pytest.raises(UnknownNameError):  # a place this home has no name like: still unknown
        predict_positions(params, 0, vocab, "garage", n=3, rng=0)
    found = resolve_name(vocab, params.word_mask, "restroom", lexicon=wordnet)
    assert found is not None and found.name == "toilet" and found.how in ("synonym", "gloss")
    unusable = resolve_name(vocab, np.array([False, True, True]), "restroom", lexicon=wordnet)
    assert unusable is None or unusable.name != "toilet"  # a pruned word is never the answer


def _living_kitchen() -> tuple[ConceptParameters, Vocabulary]:
    """Concept 0 at x = 0 says "living room" and "tv", concept 1 at x = 5 "kitchen"."""
    theta = np.array([[0.5, 0.2, 0.3, 0.0], [0.0, 0.0, 0.3, 0.7]])
    return _two_place_params(theta), Vocabulary(("living room", "tv", "is", "kitchen"))


def test_compound_names_never_heard_resolve_through_their_words_or_are_refused(wordnet) -> None:
    params, vocab = _living_kitchen()
    tv = predict_positions(params, 0, vocab, "tv room", n=5, rng=0)  # the modifier before a kind of room
    assert (tv.asked, tv.name, tv.region) == ("tv room", "tv", 0), (tv.name, tv.via)
    sitting = predict_positions(params, 0, vocab, "sitting room", n=5, rng=0)  # a WordNet synonym
    assert (sitting.name, sitting.via, sitting.region) == ("living room", "synonym", 0)
    for asked in ("cookroom", "cooking corner"):  # one word read as two; "cook" ~ "preparing meals"
        pred = predict_positions(params, 0, vocab, asked, n=5, rng=0)
        assert (pred.name, pred.via, pred.region) == ("kitchen", "definition", 1), (asked, pred.via)
    for asked in ("garage", "mudroom"):  # nothing in WordNet links them to a name of this home
        assert resolve_name(vocab, params.word_mask, asked, lexicon=wordnet) is None
        with pytest.raises(UnknownNameError, match=asked):
            predict_positions(params, 0, vocab, asked, n=3, rng=0)


def test_a_name_never_heard_is_found_by_its_modifier_s_compound_or_its_words_said_here(wordnet) -> None:
    """"comfort room" (unknown to WordNet) finds the toilet through "comfort station"; a name the
    lexicon relates to no name of the home is answered by its own words that the home's people say,
    kinds of place left out: "sink area" where "sink" is said (with "area", said most at the
    kitchen, it was the kitchen; a thing before a kind of place, it is read so first), "soaking
    room" where "soak" is said; "great room" ("great hall" is a hall, which says nothing of it)
    finds nothing."""
    vocab = Vocabulary(("toilet", "sink", "area", "room", "kitchen", "soak"))
    theta = np.array([[0.5, 0.2, 0.02, 0.2, 0.0, 0.08],  # concept 0 at x = 0: the toilet
                      [0.0, 0.1, 0.3, 0.1, 0.3, 0.2]])  # concept 1 at x = 5: the kitchen
    theta[0, 5], theta[1, 5] = 0.0, 0.2
    params = replace(_two_place_params(theta), name_prior=np.array([0.6, 0.01, 0.6, 0.6, 0.6, 0.005]))
    comfort = predict_positions(params, 0, vocab, "comfort room", n=3, rng=0)
    assert (comfort.name, comfort.via, comfort.region) == ("toilet", "compound gloss", 0), comfort.via
    sink = predict_positions(params, 0, vocab, "sink area", n=3, rng=0)
    assert (sink.name, sink.via, sink.region) == ("sink", "place word thing", 0), (sink.name, sink.via)
    together = predict_positions(params, 0, vocab, "sink area", n=3, rng=0, unheard=False)
    assert together.region == 1  # the words said together: "area" takes it to the kitchen
    soak = predict_positions(params, 0, vocab, "soaking room", n=3, rng=0)
    assert (soak.name, soak.via, soak.region) == ("soak", "its words", 1)
    assert resolve_name(vocab, params.word_mask, "great room", params.name_prior, lexicon=wordnet) is None
    assert wordnet.closest("comfort room", ["restroom", "kitchen"], similarity=False) == \
        LexiconMatch("restroom", 0.8, "compound synonym")
    assert wordnet.closest("great room", ["hall", "kitchen"], similarity=False) is None


def test_the_lexicon_reads_heads_modifiers_derivations_and_definitions(wordnet) -> None:
    assert wordnet.split_compound("mudroom") == ["mud", "room"]
    assert wordnet.split_compound("kitchen") is None and wordnet.split_compound("bath room") is None
    known = ["bedchamber", "bed", "bedroom", "laundry room", "bath", "kitchen"]
    cases = {"sleeping quarters": ("bedchamber", "definition"),  # one concept; "bed" is no place
             "laundry area": ("laundry room", "head"),  # the same words before another kind of place
             "washing area": ("laundry room", "head synonym"),  # a synonym (laundry.n.01) before one
             "bathing room": ("bath", "derivation"),  # "bathing" -> "bathe", whose synset holds "bath"
             "kitchen nook": ("kitchen", "head")}
    for asked, (name, how) in cases.items():
        found = wordnet.closest(asked, known, similarity=False)
        assert found is not None and (found.name, found.how) == (name, how), (asked, found)
    assert wordnet.closest("lounge", ["living room", "kitchen"], similarity=False) is None
    assert wordnet.closest("lounge", ["living room", "kitchen"]).name == "living room"  # similarity


def test_rooms_are_candidates_kinds_of_place_never_and_firm_names_come_first(wordnet) -> None:
    from spco.model.unheard import candidate_names

    vocab = Vocabulary(("room", "area", "toilet", "corner", "hall", "entrance", "sofa", "or"))
    prior = np.array([0.6, 0.6, 0.01, 0.3, 0.6, 0.6, 0.01, 0.01])  # "toilet": a low name prior
    info = np.array([0.3, 0.3, 0.0, 0.0, 0.02, 0.4, 0.0, 0.0])
    mask = np.ones(len(vocab.words), dtype=bool)
    candidates = candidate_names(vocab, mask, prior, wordnet, info)
    # "toilet" is a room in WordNet; "room" and "area" are kinds of place; "corner" and "sofa" neither;
    # "or" (WordNet: an operating room) is a function word
    assert candidates == ["hall", "entrance", "toilet"], candidates
    # "foyer" is a synonym of "hall" (weakly bound here) and defined as "a large entrance …": the
    # firmly bound "entrance" is used; with "hall" as firm as "entrance", the synonym
    found = resolve_name(vocab, mask, "foyer", prior, lexicon=wordnet, information=info)
    assert found is not None and (found.name, found.how) == ("entrance", "gloss")
    info[4] = 0.4
    found = resolve_name(vocab, mask, "foyer", prior, lexicon=wordnet, information=info)
    assert found is not None and (found.name, found.how) == ("hall", "synonym")
    found = resolve_name(vocab, mask, "latrine", prior, lexicon=wordnet, information=info)
    assert found is not None and found.name == "toilet"


def test_a_weakly_bound_name_found_gives_way_to_its_firmly_bound_synonym(wordnet) -> None:
    # "reception room" is in the definition of "parlour" only ("a reception room in a private
    # house"); "parlour" is a WordNet synonym of "living room", which this home binds firmly
    vocab = Vocabulary(("parlour", "living room", "kitchen"))
    mask, prior = np.ones(3, dtype=bool), np.array([0.8, 0.7, 0.7])
    found = resolve_name(vocab, mask, "reception room", prior, lexicon=wordnet,
                         information=np.array([0.001, 0.4, 0.4]))
    assert found is not None and (found.name, found.how) == ("living room", "definition synonym"), found
    found = resolve_name(vocab, mask, "reception room", prior, lexicon=wordnet,
                         information=np.array([0.4, 0.4, 0.4]))  # both firm: the name found stays
    assert found is not None and found.name == "parlour", found



def test_a_name_stands_for_a_sense_only_if_it_is_used_in_it(wordnet) -> None:
    # WordNet files "bathroom" under a toilet too (its second sense), but its tagged uses are all of the
    # room with the bathtub; "hall" is used as an anteroom in 10 of its 46 uses
    assert wordnet.seldom_in("bathroom", "privy") and wordnet.seldom_in("bathroom", "toilet")
    assert not wordnet.seldom_in("hall", "foyer") and not wordnet.seldom_in("toilet", "privy")
    assert not wordnet.seldom_in("parlour", "living room")  # no tagged use at all: no evidence
    assert not wordnet.seldom_in("kitchen", "privy")  # no shared sense
    # a home binding "bathroom" (its bath) firmly and "toilet" weakly: a "privy", a "latrine" ("a public
    # toilet …") and a "men's room" are the toilet, not the bathroom
    vocab = Vocabulary(("bathroom", "toilet", "kitchen"))
    mask, prior = np.ones(3, dtype=bool), np.array([0.8, 0.3, 0.7])
    info = np.array([0.4, 0.001, 0.4])
    for asked in ("privy", "latrine", "men's room"):
        found = resolve_name(vocab, mask, asked, prior, lexicon=wordnet, information=info)
        assert found is not None and found.name == "toilet", (asked, found)
    # a synonym in a sense the name is used in is kept, firmly bound first: "foyer" -> "hall"
    vocab = Vocabulary(("hall", "lobby", "kitchen"))
    found = resolve_name(vocab, mask, "foyer", prior, lexicon=wordnet, information=info)
    assert found is not None and (found.name, found.how) == ("hall", "synonym"), found



def test_a_name_found_gives_way_to_a_firm_synonym(wordnet) -> None:
    # "shower stall" and "shower room" find "bathroom" by its definition; WordNet files "bathroom" under
    # the toilet too (its second sense). A home binding "toilet" firmly and "bathroom" weakly: the firm
    # "toilet" stands in for it
    vocab = Vocabulary(("toilet", "bathroom", "kitchen"))
    mask, prior = np.ones(3, dtype=bool), np.array([0.8, 0.3, 0.7])
    info = np.array([0.4, 0.001, 0.4])
    for asked in ("shower stall", "shower room"):
        found = resolve_name(vocab, mask, asked, prior, lexicon=wordnet, information=info)
        assert found is not None and (found.name, found.how) == ("toilet", "definition synonym"), found
    # "parlour" (no tagged use: no evidence against it), found for "reception room" by its definition,
    # is the firmly bound "living room"
    vocab = Vocabulary(("living room", "parlour", "kitchen"))
    found = resolve_name(vocab, mask, "reception room", prior, lexicon=wordnet, information=info)
    assert found is not None and found.name == "living room", found


def test_a_kind_of_place_after_a_thing_reads_every_sense_of_the_thing(wordnet) -> None:
    # "bunk" is first a feeding trough, then a bed (three senses under bed.n.01): with nothing else
    # found, "bunk room" is where this home says "bed"; the commonest thing sense said comes first
    from spco.model.unheard import THING_SENSE

    assert wordnet.thing_sense_words("bunk")[:4] == ["bunk", "feed bunk", "manger", "trough"]
    assert "bed" in wordnet.thing_sense_words("bunk")
    assert wordnet.thing_sense_words("lounge") == []  # a place: "lounge room" is the lounge
    assert wordnet.thing_sense_words("wet") == []  # no thing sense (moisture is a state)
    vocab = Vocabulary(("bed", "kitchen", "sofa"))
    mask, prior = np.ones(3, dtype=bool), np.array([0.3, 0.7, 0.1])
    info, place = np.array([0.2, 0.4, 0.1]), np.array([0.3, 0.4, 0.2])
    for asked in ("bunk room", "bunk area", "bunkroom"):
        found = resolve_name(vocab, mask, asked, prior, lexicon=wordnet, information=info,
                             place_information=place)
        assert found is not None and (found.name, found.how) == ("bed", THING_SENSE), (asked, found)
    # without the words of a place (ψ), as the other steps through them: not asked
    assert resolve_name(vocab, mask, "bunk room", prior, lexicon=wordnet, information=info) is None
    vocab = Vocabulary(("trough", "bed", "kitchen"))
    found = resolve_name(vocab, mask, "bunk room", prior, lexicon=wordnet, information=info,
                         place_information=place)
    assert found is not None and found.name == "trough", found
    # a name whose words are not a thing before a kind of place: nothing ("great room": a great is a person)
    vocab = Vocabulary(("bed", "kitchen", "sofa"))
    assert resolve_name(vocab, mask, "great room", prior, lexicon=wordnet, information=info,
                        place_information=place) is None


def _living_washroom_objects() -> tuple[ConceptParameters, Vocabulary]:
    """Concept 0 at x = 0 is the living room ("tv", "sofa" said there as words of the place, ψ),
    concept 1 at x = 5 the washroom ("bath" said there as a thing: "take a bath"). The objects have
    a low name prior and no name information (θ^w the same at both places): no candidate names."""
    vocab = Vocabulary(("living room", "tv", "sofa", "washroom", "bath", "is"))
    theta = np.array([[0.5, 0.05, 0.05, 0.0, 0.05, 0.35],
                      [0.0, 0.05, 0.05, 0.5, 0.05, 0.35]])
    psi = np.array([[0.0, 0.45, 0.45, 0.0, 0.0, 0.1],
                    [0.0, 0.0, 0.0, 0.0, 0.9, 0.1]])
    prior = np.array([0.7, 0.01, 0.01, 0.7, 0.01, 0.01])
    return _two_place_params_with_place_words(theta, psi, prior), vocab


def test_a_name_never_heard_is_found_by_the_words_said_at_a_place(wordnet) -> None:
    """Compositional names whose words nobody said, related by WordNet to a thing said at a place
    (ψ), not to a name: "television room" and "telly room" (a television set is a "tv") where the
    tv is, "couch corner" where the sofa is, "bathing room" ("bathe", whose verb holds "bath") where
    people take a bath. Without the words of a place (``place_information`` None) they are not
    resolved, or only by WordNet similarity among the home's rooms, as before; a word said
    everywhere alike is no word of a place."""
    from spco.model.position_prediction import place_word_information
    from spco.model.prediction import mutual_information_weights
    from spco.model.unheard import PLACE_WORD, place_words

    params, vocab = _living_washroom_objects()
    info = mutual_information_weights(params, 0)
    place = place_word_information(params, 0)
    assert info[1] < 1e-3 * info.max() and place[1] > 0.1 * place.max()  # "tv": by ψ only
    assert place_words(vocab, params.word_mask, place, wordnet, exclude=["living room", "washroom"]) \
        == ["bath", "tv", "sofa"]  # by information; "is" (said alike everywhere) left out
    cases = {"television room": ("tv", 0), "telly room": ("tv", 0), "couch corner": ("sofa", 0),
             "bathing room": ("bath", 1)}
    for asked, (name, region) in cases.items():
        pred = predict_positions(params, 0, vocab, asked, n=5, rng=0)
        assert (pred.asked, pred.name, pred.region) == (asked, name, region), (asked, pred.name, pred.via)
        assert pred.via is not None and pred.via.startswith(PLACE_WORD)
        assert np.all(np.abs(pred.samples[:, 0] - 5.0 * region) < 2.0)
        before = resolve_name(vocab, params.word_mask, asked, params.name_prior, lexicon=wordnet,
                              information=info)  # no words of a place given: a guess by similarity
        assert before is None or before.how == "similarity", (asked, before)  # among rooms, or none
    # a name the lexicon relates to a name of the home keeps that name (a synonym before any thing)
    sitting = predict_positions(params, 0, vocab, "sitting room", n=3, rng=0)
    assert (sitting.name, sitting.via, sitting.region) == ("living room", "synonym", 0)
    with pytest.raises(UnknownNameError):  # related to nothing said here: still unknown
        predict_positions(params, 0, vocab, "garage", n=3, rng=0)


def test_a_modifier_s_compound_naming_a_place_comes_before_its_derivations(wordnet) -> None:
    """"dressing area": WordNet names a place by its modifier before another head, the "dressing
    room", "a room in which you can change clothes"; that place is nearer the name than a word
    derived from "dressing" ("dresser", a chest of drawers). With "clothes" said at the washroom and
    "dresser" at the bedroom, "dressing area" is looked for where clothes are said; a name whose
    modifier names no place so ("bathing room") still finds its derivation."""
    from spco.model.unheard import PLACE_WORD

    vocab = Vocabulary(("bedroom", "washroom", "dresser", "clothes", "bath", "is"))
    theta = np.array([[0.5, 0.0, 0.05, 0.05, 0.05, 0.35],
                      [0.0, 0.5, 0.05, 0.05, 0.05, 0.35]])
    psi = np.array([[0.0, 0.0, 0.9, 0.0, 0.0, 0.1],
                    [0.0, 0.0, 0.0, 0.45, 0.45, 0.1]])
    prior = np.array([0.7, 0.7, 0.01, 0.01, 0.01, 0.01])
    params = _two_place_params_with_place_words(theta, psi, prior)
    pred = predict_positions(params, 0, vocab, "dressing area", n=5, rng=0)
    assert (pred.name, pred.via, pred.region) == ("clothes", f"{PLACE_WORD} compound gloss", 1), pred.via
    assert wordnet.closest("dressing area", ["dresser", "clothes"], similarity=False) == \
        LexiconMatch("clothes", 0.9 * 0.8, "compound gloss")
    assert wordnet.closest("dressing area", ["dresser"], similarity=False) == \
        LexiconMatch("dresser", 0.7, "derivation")
    bathing = predict_positions(params, 0, vocab, "bathing room", n=5, rng=0)
    assert (bathing.name, bathing.region) == ("bath", 1), bathing.via


def test_a_kind_of_place_named_after_a_thing_is_where_this_home_says_the_thing(wordnet) -> None:
    """"washbasin area": WordNet's washbasin is also called a "lavatory" (a name of this home's toilet)
    and is "a bathroom sink"; this home says "sink" at its washroom, so the name is looked for there —
    the thing as asked, its synonyms, then its kind (a washbasin is a sink) — before the names WordNet
    relates it to. A word that can name a place ("lounge", "laundry") or a name WordNet knows whole
    ("powder room") is no thing's place; nor is a person's ("guest area") or an act's."""
    from spco.model.unheard import PLACE_WORD, THING

    vocab = Vocabulary(("lavatory", "washroom", "bathroom", "sink", "is"))
    theta = np.array([[0.5, 0.0, 0.1, 0.05, 0.35],  # concept 0 at x = 0: the toilet
                      [0.0, 0.5, 0.0, 0.05, 0.35]])  # concept 1 at x = 5: the washroom
    psi = np.array([[0.0, 0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.9, 0.1]])
    prior = np.array([0.7, 0.7, 0.7, 0.01, 0.01])
    params = _two_place_params_with_place_words(theta, psi, prior)
    pred = predict_positions(params, 0, vocab, "washbasin area", n=5, rng=0)
    assert (pred.name, pred.via, pred.region) == ("sink", f"{PLACE_WORD} {THING}", 1), (pred.name, pred.via)
    assert np.all(np.abs(pred.samples[:, 0] - 5.0) < 2.0)
    things = wordnet.thing_words("washbasin area", ["lavatory", "washroom"])
    assert things[:2] == ["washbasin", "basin"] and "lavatory" in things and things[-1] == "sink", things
    for asked in ("lounge room", "laundry area", "powder room", "guest area", "eating area", "kitchen"):
        assert wordnet.thing_words(asked, ["lavatory", "washroom"]) == [], asked
    # said nowhere more than elsewhere, the thing is still its own word, as a name's own words are
    flat = _two_place_params_with_place_words(theta, np.full((2, 5), 0.2), prior)
    assert predict_positions(flat, 0, vocab, "sink area", n=3, rng=0).name == "sink"


def test_a_phrase_of_location_says_where_a_place_is_but_what_an_act_is_done_with(wordnet) -> None:
    """"soaking room": nobody says "soak"; WordNet's soak is "… immersed in water" and this home says
    "water" at the bath: the look-up reads that phrase (it is no place's definition), and the name is
    looked for where water is said. In a place's definition a phrase of location still says where the
    place is ("dinette": "a small area off a kitchen" is no kitchen). ``what``'s stand-ins ask without
    ``located`` and read neither."""
    vocab = Vocabulary(("living room", "bath", "water", "room", "is"))
    theta = np.array([[0.5, 0.0, 0.0, 0.15, 0.35], [0.0, 0.5, 0.0, 0.15, 0.35]])
    psi = np.array([[0.0, 0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.9, 0.0, 0.1]])
    prior = np.array([0.7, 0.7, 0.01, 0.3, 0.01])
    params = _two_place_params_with_place_words(theta, psi, prior)
    pred = predict_positions(params, 0, vocab, "soaking room", n=5, rng=0)
    assert (pred.name, pred.region) == ("water", 1), (pred.name, pred.via)
    assert wordnet.closest("soaking room", ["water"], similarity=False) is None
    assert wordnet.closest("soaking room", ["water"], similarity=False, located=True).name == "water"
    assert wordnet.closest("dinette", ["kitchen"], similarity=False, located=True) is None


def test_similar_rooms_are_told_apart_by_the_definitions_of_the_asked_name_s_kinds(wordnet) -> None:
    """"rec room" ("a room equipped for informal entertaining") is as similar to every room; its own
    definition shares "equipped" with the kitchen's ("a room equipped for preparing meals"), its
    kind "family room" ("a recreation room in a private house") shares "private house" with the
    living room's: the living room (extended Lesk)."""
    found = wordnet.closest("rec room", ["kitchen", "living room"])
    assert found is not None and (found.name, found.how) == ("living room", "similarity"), found
    assert wordnet.closest("rec room", ["kitchen", "living room"], similarity=False) is None


def test_a_name_wordnet_files_under_a_known_name_is_that_name(wordnet) -> None:
    """"dining hall" is a kind of dining room in WordNet (its hypernym): the dining room, before its
    head "hall", a name of this home too; one relation away only: "mudroom" ("mud" + "room") does not
    reach "parcel" through "mud flat", a tract of land, also called a parcel."""
    found = wordnet.closest("dining hall", ["hall", "dining room"], similarity=False)
    assert found is not None and (found.name, found.how) == ("dining room", "hypernym"), found
    assert wordnet.closest("mudroom", ["parcel"], similarity=False) is None


def test_a_quality_said_at_a_place_does_not_stand_for_it(wordnet) -> None:
    """"wet" (WordNet: mostly an adjective) said only at the washroom neither answers "wet room" as its
    own word nor as a word of a place; "sink" (a noun and a verb, never a quality) answers "sink area"."""
    from spco.model.unheard import QUALITY_SHARE, place_words, said_words

    assert wordnet.quality_share("wet") > QUALITY_SHARE and wordnet.quality_share("small") > QUALITY_SHARE
    assert wordnet.quality_share("sink") == 0.0 and wordnet.quality_share("bath") == 0.0
    vocab = Vocabulary(("living room", "washroom", "wet", "sink", "room"))
    mask = np.ones(5, dtype=bool)
    assert said_words(vocab, mask, "wet room", wordnet) == []
    assert said_words(vocab, mask, "sink area", wordnet) == ["sink"]
    place = np.array([0.4, 0.4, 0.3, 0.3, 0.0])
    assert place_words(vocab, mask, place, wordnet, exclude=["living room", "washroom"]) == ["sink"]


def test_a_thing_with_many_kinds_is_a_word_of_a_place_a_kind_of_place_is_not(wordnet) -> None:
    """"water" has as many kinds below it in WordNet as "room" or "area" (≥ KINDS_BELOW), but none of
    its senses is a place: said at the bath, it is a word of that place, and "wet room" ("wet", the
    noun: moisture, "wetness caused by water") is looked for there; "room" and "area" stay out."""
    from spco.data.lexicon import KINDS_BELOW
    from spco.model.unheard import PLACE_WORD, place_words

    assert wordnet.kinds_below("water") >= KINDS_BELOW and wordnet.place_share("water") == 0.0
    vocab = Vocabulary(("living room", "bath", "water", "room", "area", "is"))
    place = np.array([0.4, 0.4, 0.3, 0.3, 0.3, 0.0])
    assert place_words(vocab, np.ones(6, dtype=bool), place, wordnet, exclude=["living room", "bath"]) \
        == ["water"]
    theta = np.array([[0.5, 0.0, 0.0, 0.15, 0.0, 0.35], [0.0, 0.5, 0.0, 0.0, 0.15, 0.35]])
    psi = np.array([[0.0, 0.0, 0.0, 0.9, 0.0, 0.1], [0.0, 0.0, 0.9, 0.0, 0.0, 0.1]])
    prior = np.array([0.7, 0.7, 0.01, 0.3, 0.3, 0.01])
    params = _two_place_params_with_place_words(theta, psi, prior)
    pred = predict_positions(params, 0, vocab, "wet room", n=5, rng=0)
    assert (pred.name, pred.region) == ("water", 1) and pred.via.startswith(PLACE_WORD), pred.via


def test_names_said_are_answered_as_before_whatever_the_lexicon_finds(wordnet) -> None:
    """The look-up acts only on a name that is not one usable token: every word said (names, things
    said at a place, function words) is answered exactly as without it."""
    for params, vocab in (_living_washroom_objects(), _living_kitchen(), _toilet_kitchen()):
        for word in vocab.words:
            looked = predict_positions(params, 0, vocab, word, n=4, rng=3)
            plain = predict_positions(params, 0, vocab, word, n=4, rng=3, unheard=False)
            assert looked.asked is None and looked.via is None and looked.name == plain.name
            np.testing.assert_array_equal(looked.region_probabilities, plain.region_probabilities)
            np.testing.assert_array_equal(looked.samples, plain.samples)


def test_place_word_information_is_the_mutual_information_of_the_words_as_where_reads_them() -> None:
    """Brute force on a tiny home: I(1[word = w]; C) from the joint table of (concept, said or not)
    under p(w | l) = p(name | w) θ_{l,w} + p(place | w) ψ_{l,w}; without ψ, the names' information."""
    from spco.model.position_prediction import place_word_information, said_word_matrix
    from spco.model.prediction import mutual_information_weights

    params, _ = _living_washroom_objects()
    said = said_word_matrix(params, 0)
    g = params.concept_weights[0] / params.concept_weights[0].sum()
    for w in range(said.shape[1]):
        joint = np.array([[g[c] * said[c, w], g[c] * (1.0 - said[c, w])] for c in range(2)])
        px = joint.sum(axis=1, keepdims=True)
        py = joint.sum(axis=0, keepdims=True)
        nz = joint > 0
        brute = float((joint[nz] * np.log(joint[nz] / (px * py)[nz])).sum())
        assert place_word_information(params, 0)[w] == pytest.approx(brute, abs=1e-12), w
    plain = replace(params, place_word_probabilities=None, word_channel_prior=None)
    np.testing.assert_allclose(place_word_information(plain, 0), mutual_information_weights(plain, 0))


def test_spco_without_wordnet_works_as_before(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SPCO_WORDNET", "off")
    assert lexicon() is None and "turned off" in (lexicon_unavailable_reason() or "")
    params, vocab = _toilet_kitchen()
    with pytest.raises(UnknownNameError):  # no lexicon: a name nobody said is unknown
        predict_positions(params, 0, vocab, "restroom", n=3, rng=0)
    assert predict_positions(params, 0, vocab, "toilet", n=3, rng=0).region == 0
    sentences = ["this is the toilet", "the toilet is here", "we eat on the table"]
    v = Vocabulary.from_sentences(sentences)
    prior = name_prior(v, sentences)  # the frames alone
    assert prior.shape == (len(v),) and np.all((prior > 0) & (prior < 1))
    assert prior[v.index("toilet")] > prior[v.index("we")]


def test_barriers_walls_and_drawers_are_not_places(wordnet) -> None:
    """NOT_PLACE_ROOTS: a door, a gate, a wall, a window, a drawer bound or hold places (WordNet files
    them under structures) and are no places; the rooms, halls, doorways and stairs they bound are."""
    for thing in ("door", "gate", "wall", "drawer", "fence"):
        assert wordnet.place_share(thing) < 0.3, (thing, wordnet.place_share(thing))  # door: doorway
    for place in ("hall", "doorway", "stairs", "porch", "garage", "bedroom"):
        assert wordnet.place_share(place) >= 0.9, place


def test_a_misspelt_or_run_together_word_takes_its_spelling_s_facts(wordnet) -> None:
    """spelling_variants: "livingroom" is "living room" run together, "bed room" is "bedroom" written
    in two (no misspelling: flag 0), "kicthen" is one edit from the vocabulary's "kitchen" (a
    misspelling: flag 1); a word of fewer than MIN_VARIANT_CHARS letters is not matched ("bde")."""
    from spco.model.name_evidence import spelling_variants

    words = ["livingroom", "bed room", "kicthen", "kitchen", "bde", "bed", "the"]
    feats = lexical_features(words, wordnet)
    known, place, variant = (FEATURES.index(f) - 6 for f in ("known", "place_share", "spelling_variant"))
    for k in (0, 1, 2):
        assert feats[k, known] == 1.0 and feats[k, place] > 0.9, words[k]
    assert feats[0, variant] == 0.0 and feats[1, variant] == 0.0 and feats[2, variant] == 1.0
    assert feats[4, known] == 0.0 and feats[3, variant] == 0.0
    assert "kitchen" in spelling_variants("kicthen", words) and spelling_variants("bde", words) == []
    assert "living room" in spelling_variants("livingroom") and spelling_variants("bed room") == ["bedroom"]


def test_an_object_said_at_a_place_stands_in_for_the_name_the_lexicon_relates_it_to(wordnet) -> None:
    """stand_in_names: "door" (an object, name evidence below OBJECT_BELOW) is in the definition of
    "door" as "the entrance to a room": the known, stronger name "entrance" stands in for it; "dining
    table" gets its modifier "dining" when that is a stronger name; "pot" (WordNet's slang synonym of
    a toilet) and "vase" (only similar to a bath) get none; a strong name is never replaced."""
    from spco.model.unheard import stand_in_names

    vocab = Vocabulary(("door", "entrance", "kitchen", "toilet", "bath", "pot", "vase", "dining table",
                        "dining"))
    prior = np.array([0.08, 0.3, 0.6, 0.2, 0.3, 0.05, 0.05, 0.03, 0.2])
    mask = np.ones(len(vocab), dtype=bool)
    out = stand_in_names(vocab, mask, prior, np.arange(len(vocab)), wordnet)
    w = vocab.words
    assert {w[k]: w[j] for k, j in out.items()} == {"door": "entrance", "dining table": "dining"}
    # the stand-in must be a stronger name than the object: with "entrance" weak, "door" stays
    weak = prior.copy()
    weak[1] = 0.05
    assert 0 not in stand_in_names(vocab, mask, weak, np.arange(len(vocab)), wordnet)
    # a spelling WordNet does not know stands in for the one it knows, when the vocabulary holds it
    spelt = Vocabulary(("livingroom", "living room", "kicthen", "kitchen", "genkan"))
    found = stand_in_names(spelt, np.ones(5, dtype=bool), np.full(5, 0.5), np.arange(5), wordnet)
    assert {spelt.words[k]: spelt.words[j] for k, j in found.items()} == {"livingroom": "living room",
                                                                         "kicthen": "kitchen"}
