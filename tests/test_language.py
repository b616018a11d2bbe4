"""Tokenizer and vocabulary: examples and properties."""

from __future__ import annotations

from collections import Counter
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spco.data.function_words import is_function_word
from spco.data.language import (
    MAX_SENTENCE_TOKENS,
    MAX_TOKEN_CHARS,
    LanguageWarning,
    Vocabulary,
    learn_terms,
    normalize_name,
    tokenize,
)
from spco.errors import ConfigurationError

pytestmark = pytest.mark.filterwarnings("ignore::spco.data.language.LanguageWarning")  # "ダイニング"

WORDS = ["kitchen", "emma's-room", "living-room", "this", "is", "the", "bath", "father's", "ダイニング"]


def test_examples() -> None:
    assert tokenize("This is Emma's-room!") == ["this", "is", "emma's room"]
    assert tokenize("Emma’s room, the LIVING-ROOM.") == ["emma's", "room", "the", "living room"]
    assert tokenize("kitchen – bath -- 'quoted' toilet's") == ["kitchen", "bath", "quoted", "toilet's"]
    assert tokenize("snake_case x2") == ["snake", "case", "x2"]
    assert tokenize(None) == [] and tokenize("") == [] and tokenize(" ,.! ") == []
    assert normalize_name("Emma's Room") == normalize_name("emma's-room") == "emma's room"


@settings(max_examples=300)
@given(st.text(max_size=80))
def test_tokens_are_clean_words(sentence: str) -> None:
    for token in tokenize(sentence):
        assert token and token == token.casefold()  # (Cherokee folds to upper case: not .lower())
        assert token == token.strip() and "  " not in token and "-" not in token
        assert token[0] not in "' " and token[-1] not in "' "
        assert not any(a in "' " and b in "' " for a, b in pairwise(token))


@settings(max_examples=300)
@given(st.text(max_size=80))
def test_tokenize_is_idempotent(sentence: str) -> None:
    tokens = tokenize(sentence)
    assert tokenize(" ".join(t.replace(" ", "-") for t in tokens)) == tokens


@given(st.lists(st.sampled_from(WORDS), max_size=12), st.sampled_from([" ", "  ", "\t", ", ", "! "]))
def test_possessive_and_hyphenated_names_stay_whole(words: list[str], sep: str) -> None:
    sentence = sep.join(w.upper() if i % 2 else w for i, w in enumerate(words))
    assert tokenize(sentence) == [w.replace("-", " ") for w in words]


sentences = st.lists(st.one_of(st.none(), st.lists(st.sampled_from([*WORDS, "unknown", "zebra"]),
                                                   max_size=10).map(" ".join)), max_size=8)


@given(sentences, st.lists(st.sampled_from(WORDS), unique=True), st.integers(1, 10_000))
def test_encode_counts_increment_times_occurrences(texts: list[str | None], vocab_words: list[str],
                                                   increment: int) -> None:
    vocab = Vocabulary(tuple(vocab_words))
    counts = vocab.encode(texts, increment)
    assert counts.shape == (len(texts), len(vocab_words)) and counts.dtype == np.int64
    dense = counts.toarray()
    for row, text in enumerate(texts):
        occurrences = Counter(vocab.tokenize(text))
        expected = [increment * occurrences[w] for w in vocab.words]
        assert dense[row].tolist() == expected  # unknown words contribute nothing
        assert vocab.unknown_words(text) == [w for w in vocab.tokenize(text) if w not in vocab.words]


@given(sentences)
def test_vocabulary_from_sentences_in_order_of_first_appearance(texts: list[str | None]) -> None:
    vocab = Vocabulary.from_sentences(texts, learn=False)
    expected = list(dict.fromkeys(w for t in texts for w in tokenize(t)))
    assert list(vocab.words) == expected
    assert all(vocab.index(w) == k for k, w in enumerate(expected))
    # "word" said apart too: no run of new words (new_word_runs) glues "a brand new word" together
    extended = vocab.extended(["a brand-new word", "word"])
    assert extended.words[: len(vocab)] == vocab.words and "brand new" in extended


def test_vocabulary_errors() -> None:
    with pytest.raises(ConfigurationError):
        Vocabulary(("a", "a"))
    with pytest.raises(ConfigurationError):
        Vocabulary(("a",)).encode(["a"], 0)


# ------------------------------------------------------------------------------ terms
def _speech(rng: np.random.Generator, n: int) -> list[str]:
    """Sentences in which people say multi-word names, with varied frames around them."""
    frames = ["this is the {}", "the {} is here", "we are in the {}", "welcome to our {}", "{} here",
              "okay so this is the {} right", "look the {}"]
    names = ["living room", "dining room", "kitchen", "front door", "bathroom", "emma's room", "toilet",
             "bedroom"]
    return [frames[rng.integers(len(frames))].format(names[rng.integers(len(names))]) for _ in range(n)]


def test_terms_are_learnt_from_the_sentences() -> None:
    sentences = _speech(np.random.default_rng(0), 300)
    vocab = Vocabulary.from_sentences(sentences)
    for term in ("living room", "dining room", "front door", "emma's room"):
        assert term in vocab.terms
    assert "room" not in vocab  # "room" never stands alone in these sentences
    assert not any(w == "the" for t in vocab.terms for w in t.split())  # a frame word: in > 50 % of sentences
    assert not any(t.startswith(("living room ", "kitchen ")) for t in vocab.terms)  # names end sentences
    # function words never make a term of their own ("is here", "you are in", "front of"): no name
    # starts or ends with one
    assert vocab.tokenize("The Living-Room is here") == ["the", "living room", "is", "here"]
    assert not any(is_function_word(t.split()[0]) or is_function_word(t.split()[-1]) for t in vocab.terms)
    k = vocab.index("living room")
    assert k is not None and vocab.index("Living Room") == vocab.index("living-room") == k
    assert vocab.words[k] == "living room"


def test_once_said_pairs_are_not_terms_but_queries_of_several_words_find_their_tokens() -> None:
    sentences = [*_speech(np.random.default_rng(1), 200), "this is the study room"]
    vocab = Vocabulary.from_sentences(sentences)
    assert "study room" not in vocab and "study" in vocab and "room" in vocab
    tokens, columns = vocab.query("Study-Room")
    assert tokens == ["study", "room"] and columns == [vocab.index("study"), vocab.index("room")]
    assert vocab.index("study room") is None


def test_term_rule_thresholds() -> None:
    assert learn_terms(["the big house"] * 2) == []  # under the minimum count
    # "big" is followed by several words: no cohesion
    assert learn_terms(["a big house", "the big house", "a big tree", "big cat"] * 3) == []
    terms = learn_terms(["open the front door", "the front door is red", "we left by the front door",
                         "the hall", "a cellar", "my cellar is cold"] * 3)
    assert "front door" in terms and not any("the" in t.split() for t in terms)  # "the": 4 of 6 sentences


def test_a_sentence_said_again_counts_once_unless_its_words_are_never_said_apart() -> None:
    """Vocabulary.from_sentences counts each distinct sentence once ("big bedroom" said 10 times is
    no term while "bedroom" is also said alone), but a robot's teacher saying "this is the living
    room" at every visit still teaches the term: "living" and "room" are never said apart."""
    others = ["this is the kitchen", "the kitchen", "a bath", "the bath is here", "the hall", "a toilet",
              "our toilet"]
    said_again = ["big bedroom"] * 10 + ["the bedroom", "a bedroom here"] + others * 2
    assert "big bedroom" in learn_terms(said_again)  # counting repeats, as before
    assert Vocabulary.from_sentences(said_again).terms == ()
    tour = (["this is the kitchen"] * 7 + ["this is the living room"] * 6 + ["this is the bedroom"] * 7) * 3
    vocab = Vocabulary.from_sentences(tour)
    assert vocab.terms == ("living room",) and "living" not in vocab and "room" not in vocab
    # said fewer than min_count times: no term
    twice = ["this is the living room"] * 2 + ["this is the kitchen"] * 4
    assert Vocabulary.from_sentences(twice).terms == ()
    assert learn_terms(tour, distinct=True) == ["living room"]


def test_a_frame_does_not_swallow_the_first_word_of_a_name() -> None:
    """Where two candidate pairs overlap, the stronger is joined: "in emma's" (3 times) loses to
    "emma's room" (every use of "emma's"), so "we are in emma's room now" keeps the name whole; a
    pair that never wins a sentence is no term."""
    others = ["this is emma's room", "emma's room", "hello emma's room", "this is the kitchen",
              "the kitchen is here", "a bath", "a toilet", "the hall", "my bath"]
    sentences = ["we are in emma's room now"] * 3 + others * 2
    terms = learn_terms(sentences)
    assert "emma's room" in terms and "in emma's" not in terms
    assert not any("emma's" in t.split() and t != "emma's room" for t in terms), terms
    assert Vocabulary.from_sentences(sentences).tokenize("we are in Emma's room now")[-2:] == ["emma's room",
                                                                                               "now"]


def test_a_coordinated_possessive_name_comes_out_whole() -> None:
    """"mum and dad's room" is one term ("mum and dad's" is one atom before pairs are joined: pair by
    pair neither "mum and" nor "and dad's" may be a term); "walk-in closet" still is (a hyphenated
    atom); "my room" is not (a possessive pronoun is the determiner, not part of the name)."""
    family = ["mum and dad's room", "this is mum and dad's room", "mum and dad's room here",
              "we sleep in mum and dad's room", "the kitchen", "a bath", "the hall", "this is a toilet",
              "dad's room is here", "the big sofa", "cooking in the kitchen", "shoes at the door",
              "our toilet"]
    vocab = Vocabulary.from_sentences(family)
    assert vocab.terms == ("mum and dad's room",), vocab.terms
    assert vocab.tokenize("we sleep in Mum and Dad's room") == ["we", "sleep", "in", "mum and dad's room"]
    said = ["this is my room", "my room is here", "in my room", "the walk-in closet", "a walk-in closet here",
            "my walk-in closet", "the kitchen", "a bath", "the hall", "this is a toilet", "our toilet"] * 2
    terms = learn_terms(said)
    assert "walk in closet" in terms and "my room" not in terms, terms
    assert Vocabulary.from_sentences(said).tokenize("this is my room") == ["this", "is", "my", "room"]


def test_a_term_holds_no_closed_class_word_at_a_join() -> None:
    """A learnt term is a noun phrase without its determiner (rule 4b): a verb's object phrase
    ("wash your hands", said so often that pair by pair it would be a term) is not one, nor is the
    possessive pronoun's phrase ("your hands"); a possessive noun ("emma's room") and a compound
    ("washing machine") are. Before the rule: "wash your hands" and "your hands" were terms."""
    filler = ["the kitchen", "a bath", "the hall", "this is a toilet", "the big sofa", "shoes at the door",
              "next to the washing machine", "by the washing machine", "the washing machine is here",
              "this is emma's room", "emma's room", "in emma's room now"]
    said = ["where you can wash your hands after", "wash your hands here", "you wash your hands"] * 2
    terms = learn_terms(said + filler)
    assert "washing machine" in terms and "emma's room" in terms, terms
    assert not any(w in t.split() for t in terms for w in ("your", "wash", "hands")), terms
    assert not learn_terms([s.replace("your", "the") for s in said]), "an article joins nothing"


def test_a_grown_vocabulary_learns_terms_of_new_words_only() -> None:
    vocab = Vocabulary.from_sentences(["this is the living room", "the kitchen", "a room"] * 2)
    assert "living room" not in vocab.terms and "room" in vocab  # said twice: no term yet
    grown = vocab.extended(["this is the study room", "my study room", "the study room is here",
                            "study room", "we work in the study room",
                            "the living room", "our living room", "living room here", "the kitchen",
                            "kitchen", "the hall", "a hall", "hall here", "by the stove", "the stove",
                            "the bath", "bath here", "a toilet"])
    assert grown.words[: len(vocab)] == vocab.words
    assert "study room" in grown.terms  # "study" is new
    assert "living room" not in grown  # both words known: their columns keep their occurrences
    assert grown.tokenize("this is the living room") == vocab.tokenize("this is the living room")
    assert vocab.extended(["the study room"] * 5, learn=False).tokenize("study room") == ["study", "room"]


def test_old_vocabularies_with_hyphens_read_as_terms() -> None:
    vocab = Vocabulary(("this", "living-room", "Emma's-Room"))
    assert vocab.words == ("this", "living room", "emma's room")
    assert vocab.tokenize("this living room, EMMA’S ROOM") == ["this", "living room", "emma's room"]
    counts = vocab.encode(["this is the living room", "living-room"], 2).toarray()
    assert counts.tolist() == [[2, 2, 0], [0, 2, 0]]


# ------------------------------------------------------------------------------ any text
def test_unicode_is_normalised_and_kept() -> None:
    assert tokenize("ＬＩＶＩＮＧ Straße CAFÉ") == ["living", "strasse", "café"]
    assert tokenize("cafe\u0301") == ["café"]  # NFKC composes the accent
    assert tokenize("हिन्दी कमरा") == ["हिन्दी", "कमरा"]  # combining marks stay in the word
    assert tokenize("the 🛁 room 👍🏽!") == ["the", "🛁", "room", "👍🏽"]
    assert tokenize("гостиная комната") == ["гостиная", "комната"]
    vocab = Vocabulary.from_sentences(["это гостиная 🛋️"] * 4)
    assert vocab.index("Гостиная") is not None and vocab.index("🛋️") is not None


def test_text_without_spaces_is_one_token_with_a_warning() -> None:
    with pytest.warns(LanguageWarning, match="without spaces"):
        assert tokenize("ここはリビングです") == ["ここはリビングです"]
    with pytest.warns(LanguageWarning, match="without spaces"):
        assert tokenize("这是 厨房") == ["这是", "厨房"]


def test_over_long_input_is_cut_with_a_warning() -> None:
    with pytest.warns(LanguageWarning, match="cut"):
        tokens = tokenize(" ".join(["word"] * (MAX_SENTENCE_TOKENS + 50)))
    assert len(tokens) == MAX_SENTENCE_TOKENS
    with pytest.warns(LanguageWarning, match="cut"):
        (token,) = tokenize("a" * (MAX_TOKEN_CHARS * 3))
    assert len(token) == MAX_TOKEN_CHARS


def test_new_words_said_together_once_form_a_term() -> None:
    """"this is the study room", the first sentence with "study" and "room", gives the term "study
    room" at once; a word also said apart, or a run with a known word, does not join."""
    from spco.data.language import Vocabulary

    known = Vocabulary(("this", "is", "the", "kitchen", "here"))
    assert known.new_word_runs(["this is the study room"]) == ["study room"]
    assert known.new_word_runs(["this is the study room", "the study is here"]) == []
    assert known.new_word_runs(["this is the kitchen"]) == []
    assert known.new_word_runs(["this is the big kitchen"]) == []  # "big" alone: no run of two
    grown = known.extended(["this is the study room"])
    assert grown.words[:5] == known.words and "study room" in grown.words
    assert "room" not in grown.words and "study" not in grown.words
    assert grown.tokenize("This is the Study-Room") == ["this", "is", "the", "study room"]


def test_a_run_of_new_words_is_cut_at_its_function_words() -> None:
    """All words new: a run of new words keeps no leading function word but a possessive and no
    trailing one, so the name in "we call it mum and dad's room" is a term of its own and "i cook",
    "don't touch" are no terms."""
    from spco.data.language import Vocabulary

    empty = Vocabulary(("kitchen",))
    assert empty.new_word_runs(["we call it mum and dad's room"]) == ["mum and dad's room"]
    assert empty.new_word_runs(["my room"]) == ["my room"]
    assert empty.new_word_runs(["i cook here"]) == []
    assert empty.new_word_runs(["don't touch"]) == []
    grown = empty.extended(["we call it mum and dad's room"])
    assert grown.tokenize("we call it mum and dad's room") == ["we", "call", "it", "mum and dad's room"]


def test_a_query_inside_a_longer_term_finds_it() -> None:
    """A name taught once with a trailing word ("grandma's room downstairs") is still found by its
    words; a trailing filler ("okay") is no part of the term."""
    from spco.data.language import Vocabulary

    okay = Vocabulary(("this", "is", "the")).extended(["well this is grandma's room okay"])
    assert "grandma's room" in okay.words and "okay" in okay.words
    grown = Vocabulary(("this", "is", "the")).extended(["well this is grandma's room downstairs"])
    term = "grandma's room downstairs"
    assert term in grown.words
    assert grown.query("Grandma's room") == ([term], [grown.words.index(term)])
    assert grown.query("grandma") == (["grandma"], [])  # not a whole word of the term: unknown


def test_a_name_asked_with_its_article_is_the_name() -> None:
    """`where the kids' bedroom` asks for the term "kids bedroom" (the tokenizer's plural possessive),
    not for "the" beside it; "the" alone is still a query of its own."""
    from spco.data.language import Vocabulary

    vocab = Vocabulary(("this", "is", "the", "my")).extended(["this is the kids' bedroom"] * 4
                                                             + ["we call it the kids' bedroom"] * 3)
    assert "kids bedroom" in vocab.words
    k = vocab.words.index("kids bedroom")
    for asked in ("the kids' bedroom", "The Kids\u2019 bedroom", "my kids' bedroom", "kids' bedroom"):
        assert vocab.query(asked) == (["kids bedroom"], [k]), asked
    assert vocab.query("the") == (["the"], [vocab.words.index("the")])


def test_compounds_the_lexicon_knows_are_terms_without_the_follow_share(wordnet) -> None:
    """Rule 6: "dining" is said with "table", "room" and "space", followed by none in half of its
    uses (rule 3 fails), yet "dining room" and "dining table" are WordNet nouns, and "bath room" is
    "bathroom" written in two: terms. "dining space" (no WordNet noun) is not one by rule 6, and
    without the lexicon (``lexicon=False``) none is."""
    sentences = ["this is the dining room", "near the dining table", "the dining space", "a dining room",
                 "by the dining table", "our dining room here", "the dining table is big", "dining space",
                 "we eat in the dining room", "dining room", "a dining table", "my dining space",
                 "the bath room", "a bath room", "the bath room is here", "bath room", "our bath room",
                 "a bath", "the bath is hot", "this bath", "a hot bath", "the bath", "my bath",
                 "a kitchen", "the kitchen here", "in the hall", "my hall", "a toilet", "kitchen",
                 "the toilet is here", "our kitchen", "a big hall", "go to the toilet", "hall"]
    terms = learn_terms(sentences, distinct=True)
    assert {"dining room", "dining table", "bath room"} <= set(terms), terms
    assert "dining space" not in terms
    assert not {"dining room", "dining table", "bath room"} & set(learn_terms(sentences, distinct=True,
                                                                               lexicon=False))
    # a frame word is no part of a compound, whatever WordNet says ("the" in half the sentences)
    assert not any(t.split()[0] in ("the", "a", "this") for t in terms)


def test_the_terms_holding_a_run_of_words_are_those_a_brute_force_finds() -> None:
    """``Vocabulary.terms_holding`` (what ``query`` falls back on and ``where`` reads a word of one token
    by) is, for every run of words, the terms holding it side by side in vocabulary order, as a scan
    of every term finds them; built once per vocabulary, never shared with another."""
    from spco.data.language import Vocabulary

    rng = np.random.default_rng(3)
    atoms = ["a", "b", "c", "dining", "room"]
    for _ in range(20):
        terms = {" ".join(rng.choice(atoms, size=rng.integers(2, 5))) for _ in range(8)}
        vocabulary = Vocabulary(tuple(dict.fromkeys([*atoms, *sorted(terms)])))
        runs = {" ".join(w.split()[i:j]) for w in vocabulary.words for j in range(len(w.split()) + 1)
                for i in range(j)} | {"x", "a x", "room a b c dining room"}
        for run in runs:
            r = run.split()
            expected = tuple(k for k, w in enumerate(vocabulary.words) if " " in w and any(
                w.split()[i:i + len(r)] == r for i in range(len(w.split()) - len(r) + 1)))
            assert vocabulary.terms_holding(run) == expected, run
            assert vocabulary.terms_holding(f"  {run} ") == expected
        assert vocabulary.terms_holding("") == ()
    other = Vocabulary(("dining", "dining room"))
    assert other.terms_holding("dining") == (1,) and Vocabulary(("dining",)).terms_holding("dining") == ()
