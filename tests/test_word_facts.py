"""The file caches of WordNet's word facts (spco.data.word_facts.word_facts) and kind facts
(spco.data.word_facts.kind_facts): the same numbers as the lexicon, read without loading WordNet once
known, rewritten when missing or of another format."""

from __future__ import annotations

import json

import numpy as np
import pytest

from spco.data import lexicon as lexicon_module
from spco.data import word_facts as facts_module
from spco.data.language import Vocabulary
from spco.model.name_evidence import channel_evidence, lexical_features

WORDS = ["kitchen", "emma's room", "room", "the", "genkan", "sofa", "living room", "greet"]


@pytest.fixture()
def empty_cache(tmp_path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("SPCO_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(facts_module, "_facts_memory", {})
    monkeypatch.setattr(facts_module, "_kinds_memory", {})
    monkeypatch.setattr(facts_module, "_closest_memory", {})
    return tmp_path


@pytest.fixture()
def from_files_alone(monkeypatch: pytest.MonkeyPatch):
    """Call it to read the lexicon as a new process would, from the cache files alone: the facts in
    memory are forgotten and loading WordNet fails the test."""
    def forbid_wordnet() -> None:
        def no_wordnet(folder: str):
            raise AssertionError("WordNet loaded although every word's facts are in the cache files")

        monkeypatch.setattr(facts_module, "_load", no_wordnet)
        monkeypatch.setattr(facts_module, "_facts_memory", {})
        monkeypatch.setattr(facts_module, "_kinds_memory", {})
        monkeypatch.setattr(facts_module, "_closest_memory", {})

    return forbid_wordnet


def test_cached_features_equal_the_lexicon_s_and_need_no_wordnet_once_known(
        wordnet, empty_cache, from_files_alone) -> None:
    direct = lexical_features(WORDS, wordnet)
    first = lexical_features(WORDS)  # computes and writes the file
    np.testing.assert_array_equal(first, direct)
    files = list(empty_cache.glob("wordnet-facts-*.json"))
    assert len(files) == 1 and json.loads(files[0].read_text())["format"] == facts_module._FACTS_FORMAT
    from_files_alone()
    np.testing.assert_array_equal(lexical_features(WORDS), direct)


def test_a_file_of_another_format_or_broken_is_computed_again(wordnet, empty_cache) -> None:
    lexical_features(["kitchen"])
    path = next(empty_cache.glob("wordnet-facts-*.json"))
    for text in ('{"format": 999, "words": {"kitchen": [false, null, null]}}', "not json"):
        path.write_text(text)
        facts_module._facts_memory.clear()
        facts = facts_module.word_facts(["kitchen"])
        assert facts is not None and facts["kitchen"].known and facts["kitchen"].place_share >= 0.99
        assert json.loads(path.read_text())["format"] == facts_module._FACTS_FORMAT


def test_no_facts_without_the_lexicon(monkeypatch: pytest.MonkeyPatch, empty_cache) -> None:
    monkeypatch.setenv("SPCO_WORDNET", "off")
    assert facts_module.word_facts(["kitchen"]) is None
    features = lexical_features(["kitchen", "the"])
    assert features[0].tolist() == [0.0, 0.5, 0.0, 0.0, 0.0] and features[1, 3] == 1.0


#: Place words of which some are kinds of others ("room" of "bedroom", "kitchen", "bathroom") or have
#: many kinds below them ("area", "place"), beside names and other words.
KIND_SENTENCES = ["this is the bedroom", "this is the kitchen", "this is the bathroom",
                  "this room is the study", "the area by the window", "a place to sit", "the living room",
                  "this is emma's room",
                  "here is the sofa", "the genkan"]


def test_cached_kind_facts_give_the_lexicon_s_evidence_and_need_no_wordnet_once_known(
        wordnet, empty_cache, from_files_alone) -> None:
    vocabulary = Vocabulary.from_sentences(KIND_SENTENCES)
    direct = channel_evidence(vocabulary, KIND_SENTENCES, wordnet)
    nu, content = channel_evidence(vocabulary, KIND_SENTENCES)  # computes and writes both files
    np.testing.assert_array_equal(nu, direct[0])
    np.testing.assert_array_equal(content, direct[1])
    room = vocabulary.index("room")
    assert room is not None and nu[room] < 0.1 * nu[vocabulary.index("kitchen")]  # a kind of place
    files = list(empty_cache.glob("wordnet-kinds-*.json"))
    assert len(files) == 1 and json.loads(files[0].read_text())["format"] == facts_module._KINDS_FORMAT
    from_files_alone()
    again = channel_evidence(vocabulary, KIND_SENTENCES)
    np.testing.assert_array_equal(again[0], direct[0])
    np.testing.assert_array_equal(again[1], direct[1])


#: One household's names of its toilet, of which WordNet has "toilet" and "bathroom" (its sense
#: toilet.n.01) as the hypernym of three ("loo", "restroom", "washroom"), beside other places and the
#: kind words "room" and "area".
SYNONYM_SENTENCES = ["this is the toilet", "the loo is here", "this is the restroom", "the washroom",
                     "this is the bathroom", "this is the bedroom", "this is the kitchen", "the living room",
                     "this room is the study", "the area by the window"]


@pytest.mark.parametrize("cached", [False, True])
def test_names_of_one_place_that_are_wordnet_kinds_of_one_another_keep_their_name_evidence(
        wordnet, empty_cache, cached: bool) -> None:
    """A place word is a kind of place by the kinds WordNet has under it ("room", "area"), not by
    being the WordNet hypernym of other names said: "toilet" and "bathroom" are hypernyms of "loo",
    "restroom" and "washroom", a household's names of the same place, and keep their name evidence
    (before, they got a tenth of it, and the synthetic free-form homes' and speech_dev_words.csv's
    bath lost its one name-like word, "bathroom")."""
    from spco.model.name_evidence import KIND_FACTOR, name_prior

    vocabulary = Vocabulary.from_sentences(SYNONYM_SENTENCES)
    lexicon = None if cached else wordnet
    nu, _ = channel_evidence(vocabulary, SYNONYM_SENTENCES, lexicon)
    prior = name_prior(vocabulary, SYNONYM_SENTENCES, lexicon)
    hypernyms = {"toilet", "bathroom"}
    for word in hypernyms:
        k = vocabulary.index(word)
        assert k is not None
        heads = wordnet.kind_heads(word)
        said = [w for w in ("loo", "restroom", "washroom") if heads & wordnet.kind_ancestors(w)]
        assert len(said) == 3, (word, said)  # WordNet has it as their kind
        assert nu[k] == pytest.approx(prior[k]), word  # and it keeps its name evidence
    for word in ("room", "area"):  # kinds of place
        k = vocabulary.index(word)
        assert k is not None and nu[k] == pytest.approx(KIND_FACTOR * prior[k]), word


@pytest.mark.parametrize("from_files", [False, True])
def test_an_object_stands_in_only_for_a_place_its_definition_names(wordnet, empty_cache, from_files,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """An object whose WordNet definition names a thing, not a place, stands in for nothing through
    it: "bathtub" ("a relatively large open container that you fill with water …") and "shower"
    ("a plumbing fixture that sprays water over you") are not counted for "water", a substance whose
    name evidence is above OBJECT_BELOW (before, every object of a bath counted for "water" and the
    bath was answered "water"); "door" still stands in for "entrance", a place its definition names,
    with the lexicon and through its cache files alike."""
    from spco.model import unheard

    vocab = Vocabulary(("bathtub", "shower", "water", "bathroom", "door", "entrance"))
    prior = np.array([0.04, 0.04, 0.26, 0.68, 0.08, 0.3])
    monkeypatch.setattr(unheard, "_STAND_IN_CACHE", {})
    out = unheard.stand_in_names(vocab, np.ones(len(vocab), dtype=bool), prior, np.arange(len(vocab)),
                                 None if from_files else wordnet)
    assert {vocab.words[k]: vocab.words[j] for k, j in out.items()} == {"door": "entrance"}
    match = wordnet.closest("bathtub", ["water", "bathroom"])  # the relation the test rests on
    assert match is not None and match.name == "water" and match.how.endswith("gloss")


def test_stand_ins_from_the_cache_files_equal_the_lexicon_s_and_need_no_wordnet_once_asked(
        wordnet, empty_cache, from_files_alone, monkeypatch: pytest.MonkeyPatch) -> None:
    """stand_in_names without a lexicon asks the lexicon's cache files (word facts and
    closest_names): the same stand-ins as the lexicon, and a new process whose questions are all in
    the files never loads WordNet."""
    from spco.model import unheard

    vocab = Vocabulary(("door", "entrance", "kitchen", "toilet", "bath", "pot", "vase", "dining table",
                        "dining", "livingroom", "living room", "kicthen", "genkan"))
    prior = np.array([0.08, 0.3, 0.6, 0.2, 0.3, 0.05, 0.05, 0.03, 0.2, 0.5, 0.5, 0.5, 0.5])
    mask = np.ones(len(vocab), dtype=bool)
    asked = np.arange(len(vocab))
    monkeypatch.setattr(unheard, "_STAND_IN_CACHE", {})
    direct = unheard.stand_in_names(vocab, mask, prior, asked, wordnet)
    assert {vocab.words[k]: vocab.words[j] for k, j in direct.items()} == {
        "door": "entrance", "dining table": "dining", "livingroom": "living room", "kicthen": "kitchen"}
    monkeypatch.setattr(unheard, "_STAND_IN_CACHE", {})
    assert unheard.stand_in_names(vocab, mask, prior, asked) == direct  # computes and writes the files
    files = list(empty_cache.glob("wordnet-closest-*.json"))
    assert len(files) == 1 and json.loads(files[0].read_text())["format"] == facts_module._CLOSEST_FORMAT
    from_files_alone()
    monkeypatch.setattr(unheard, "_STAND_IN_CACHE", {})
    assert unheard.stand_in_names(vocab, mask, prior, asked) == direct
    monkeypatch.setenv("SPCO_WORDNET", "off")
    monkeypatch.setattr(unheard, "_STAND_IN_CACHE", {})
    assert unheard.stand_in_names(vocab, mask, prior, asked) == {}


_FILL = """
import json, os, sys, time
go = sys.argv[1]
while not os.path.exists(go):
    time.sleep(0.01)
from spco.data import word_facts as lexicon
facts = lexicon.word_facts(json.loads(sys.argv[2]))
print(json.dumps({"loaded": lexicon._load.cache_info().currsize == 1,
                  "facts": {w: [f.known, f.noun_share, f.place_share] for w, f in facts.items()}}))
"""


def test_two_processes_missing_the_same_words_load_wordnet_once(wordnet, tmp_path) -> None:
    """spco demo's two processes on a first run: one loads WordNet and fills the file, the other
    waits for it and reads the same facts (the file's lock), whichever starts first."""
    import os
    import subprocess
    import sys

    go = tmp_path / "go"
    env = {**os.environ, "SPCO_CACHE_DIR": str(tmp_path / "cache")}
    procs = [subprocess.Popen([sys.executable, "-c", _FILL, str(go), json.dumps(WORDS)], env=env,
                              stdout=subprocess.PIPE, text=True) for _ in range(2)]
    go.touch()
    results = [json.loads(p.communicate(timeout=300)[0].strip().splitlines()[-1]) for p in procs]
    assert sorted(r["loaded"] for r in results) == [False, True]
    assert results[0]["facts"] == results[1]["facts"]
    assert set(results[0]["facts"]) == set(WORDS)


def test_the_reader_s_plain_text_reads_give_nltk_s_own_tables(wordnet, tmp_path) -> None:
    """The files read through once as plain text (``wordnet_files.READ_THROUGH``) fill the same lemma
    index, exception lists and lexicographer files as NLTK's own seekable reader; the files read at
    byte offsets still go through NLTK's reader."""
    import warnings

    from nltk.corpus.reader.wordnet import WordNetCorpusReader

    from spco.data import wordnet_files

    root = wordnet_files.reader_folder(lexicon_module._wordnet_folder(), tmp_path)
    ours = wordnet_files.open_reader(root)
    class Theirs(WordNetCorpusReader):
        def map_wn(self, version: str = "wordnet") -> None:  # (as ours: no mapping to fetch)
            return None

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        theirs = Theirs(str(root), None)
    assert len(ours._lemma_pos_offset_map) > 100_000
    assert ours._lemma_pos_offset_map == theirs._lemma_pos_offset_map
    assert ours._exception_map == theirs._exception_map
    assert ours._lexnames == theirs._lexnames
    with ours.open("index.noun") as a, theirs.open("index.noun") as b:
        assert type(a) is not type(b)  # (the plain file)
    with ours.open("data.noun") as a, theirs.open("data.noun") as b:
        assert type(a) is type(b)  # (NLTK's seekable reader)
    assert ours.synset("kitchen.n.01").definition() == theirs.synset("kitchen.n.01").definition()
    assert ours.morphy("bedrooms", "n") == theirs.morphy("bedrooms", "n") == "bedroom"


@pytest.mark.parametrize("collecting", [True, False])
def test_the_reader_builds_its_index_without_the_garbage_collector_and_restores_it(
        wordnet, monkeypatch: pytest.MonkeyPatch, collecting: bool) -> None:
    """NLTK's index of WordNet is built with the cyclic garbage collector paused (its full passes walk
    every object of a loaded server: seconds), and the collector is left as it was; the index is NLTK's."""
    import gc
    from pathlib import Path

    from nltk.corpus.reader.wordnet import WordNetCorpusReader

    from spco.data.wordnet_files import open_reader

    seen: list[bool] = []
    build = WordNetCorpusReader._load_lemma_pos_offset_map

    def spy(self) -> None:
        seen.append(gc.isenabled())
        build(self)

    monkeypatch.setattr(WordNetCorpusReader, "_load_lemma_pos_offset_map", spy)
    was = gc.isenabled()
    try:
        (gc.enable if collecting else gc.disable)()
        reader = open_reader(Path(wordnet._wn.root.path))
        assert gc.isenabled() is collecting
    finally:
        (gc.enable if was else gc.disable)()
    assert seen == [False]
    assert reader._lemma_pos_offset_map == wordnet._wn._lemma_pos_offset_map
    assert reader.synset("kitchen.n.01").definition() == wordnet._wn.synset("kitchen.n.01").definition()
