"""Speech written without spaces: segmenters chosen by script or option, a lexicon learnt from the
sentences, recorded with the vocabulary (spco.data.segmentation)."""

from __future__ import annotations

import json
import pickle
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import spco.data.segmentation as segmentation
from spco.data.language import LanguageWarning, Vocabulary, normalize_name, tokenize
from spco.data.segmentation import Segmentation, resolve, script_language, written_with_spaces
from spco.errors import ConfigurationError

# names a Japanese dictionary does not know, said in hiragana the way a recogniser prints them (the
# topic particle は as わ), as in the CC4F recording; a segmenter cuts them into pieces, not always
# the same way
NAMES = ["はぎわらけん", "にしかわけん", "きたのけん", "らっくけん", "かいだんまえ"]
FRAMES = ["ここわ{}です", "ここが{}", "{}にきました", "{}です", "このばしょのなまえわ{}", "{}だよ"]
SENTENCES = [f.format(n) for n in NAMES for f in FRAMES]


@pytest.fixture(scope="module")
def sudachi() -> None:
    pytest.importorskip("sudachipy", reason="SudachiPy is not installed (pip install -e '.[ja]')")
    pytest.importorskip("sudachidict_core", reason="sudachidict_core is not installed "
                                                   "(pip install -e '.[ja]')")


@pytest.fixture(scope="module")
def jieba() -> None:
    pytest.importorskip("jieba", reason="jieba is not installed (pip install -e '.[zh]')")


# ------------------------------------------------------------------------------ scripts (no segmenter)
def test_script_and_spacing_are_found_from_the_text() -> None:
    assert script_language(["this is the kitchen", None]) is None
    assert script_language(["ここは台所です", "this is it"]) == "ja"
    assert script_language(["这里是厨房"]) == "zh"
    assert script_language(["ห้องครัว"]) == "other"
    assert written_with_spaces(["ここ わ といれ です", "つぼけん です", "ごみばこ"])
    assert not written_with_spaces(["ここわといれです", "つぼけんです", "ここ が"])
    assert not written_with_spaces(["the kitchen"])


def test_names_compare_without_spaces_in_such_scripts() -> None:
    assert normalize_name("エマ の 部屋") == normalize_name("エマの部屋") == "エマの部屋"
    assert normalize_name("Emma's-Room") == "emma's room"
    assert normalize_name("リビング room") == "リビング room"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a name is a name: no warning about missing spaces
        assert normalize_name("はぎわらけん") == "はぎわらけん"


def test_spaced_japanese_is_not_segmented_and_not_warned_about() -> None:
    spaced = [f.format(n) for n in ("といれ", "ごみばこ", "かいぎしつ")
              for f in ("ここ わ {} です", "{} に き まし た", "ここ が {}", "{} です", "{} だ よ")]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        vocabulary = Vocabulary.from_sentences(spaced)
        assert vocabulary.tokenize("ここ わ といれ です")[-2:] == ["といれ", "です"]
        assert vocabulary.tokenize("ここわといれです") == ["ここわといれです"]  # not segmented
    assert vocabulary.segmentation == Segmentation("ja")
    assert not vocabulary.segmentation.segments
    assert Vocabulary.from_sentences(["this is the kitchen"] * 3).segmentation is None


def test_bad_languages_and_a_missing_segmenter_are_reported(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ConfigurationError, match="text language must be one of"):
        resolve("klingon", ["ここ"])
    with pytest.raises(ConfigurationError, match="segmentation language"):
        Segmentation("th")
    with pytest.raises(ConfigurationError, match="not 'jieba'"):
        Segmentation("ja", "jieba")

    class Missing:
        def __init__(self) -> None:
            raise ImportError("No module named 'sudachipy'")

    segmentation._backend.cache_clear()
    monkeypatch.setattr(segmentation, "_Sudachi", Missing)
    try:
        with pytest.raises(ConfigurationError, match=r"pip install 'spco\[ja\]'"):
            resolve("ja", SENTENCES)
        monkeypatch.setattr(segmentation, "available", lambda language: False)
        with pytest.warns(LanguageWarning, match=r"spco\[ja\]"):
            assert resolve("auto", SENTENCES) is None  # each run stays one token, as before
    finally:
        segmentation._backend.cache_clear()


def test_lexicon_files_are_checked() -> None:
    with pytest.raises(ConfigurationError, match="lexicon counts must be integers"):
        Segmentation.from_dict({"language": "ja", "segmenter": "sudachipy", "lexicon": {"ここ": "7"}})
    with pytest.raises(ConfigurationError, match="counts >= 1"):
        Segmentation.from_dict({"language": "ja", "segmenter": "sudachipy", "lexicon": {"ここ": 0}})
    with pytest.raises(ConfigurationError, match="'language'"):
        Segmentation.from_dict({"lexicon": {}})


# ------------------------------------------------------------------------------ Japanese
def test_unknown_names_come_out_whole_in_every_sentence(sudachi: None) -> None:
    """The segmenter cuts はぎわらけん into pieces, differently by context (ここわはぎわらけんです:
    わ|は|ぎわ|ら|けん); the learnt lexicon gives the whole name in every sentence."""
    raw = Segmentation("ja", "sudachipy")
    assert raw.split("ここわはぎわらけんです") != raw.split("はぎわらけんです")[:1]
    assert "はぎわらけん" not in raw.split("ここわはぎわらけんです")
    vocabulary = Vocabulary.from_sentences(SENTENCES)
    assert vocabulary.segmentation is not None and vocabulary.segmentation.segments
    for sentence in SENTENCES:
        name = next(n for n in NAMES if n in sentence)
        assert name in vocabulary.tokenize(sentence), sentence
    for name in NAMES:  # asked for alone
        assert vocabulary.query(name) == ([name], [vocabulary.words.index(name)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        vocabulary.tokenize("ここわはぎわらけんです")


def test_names_do_not_take_the_particle_after_them(sudachi: None) -> None:
    """台所 is followed by です in most sentences; it stays a word of its own (a name does not take
    the copula after it), written with or without spaces."""
    unspaced = [f.format(n) for f in ("ここは{}です", "この場所は{}です", "{}はここです", "ここが{}だよ")
                for n in ("台所", "キッチン", "寝室", "ベッドルーム", "玄関")] * 2
    spaced = [f.format(n) for f in ("ここ は {} です", "この 場所 は {} です", "{} は ここ です",
                                    "ここ が {} だ よ")
              for n in ("台所", "キッチン", "寝室", "ベッドルーム", "玄関")] * 2
    for sentences in (unspaced, spaced):
        vocabulary = Vocabulary.from_sentences(sentences)
        for name in ("台所", "キッチン", "寝室", "ベッドルーム"):
            assert name in vocabulary.words, (name, vocabulary.words)
    assert Vocabulary.from_sentences(unspaced).tokenize("ここは台所です")[-2:] == ["台所", "です"]


def test_segmentation_is_kept_by_growing_pickling_and_files(sudachi: None) -> None:
    vocabulary = Vocabulary.from_sentences(SENTENCES)
    seg = vocabulary.segmentation
    assert seg is not None
    grown = vocabulary.extended(["ここわつぼけんです", "つぼけんにきました"])
    assert grown.words[:len(vocabulary)] == vocabulary.words and "つぼけん" in grown.words
    assert grown.segmentation is not None
    assert all(grown.segmentation.count(u) == c for u, c in seg.lexicon)  # known counts unchanged
    for sentence in SENTENCES:  # text cut before is cut the same way after
        assert grown.tokenize(sentence) == vocabulary.tokenize(sentence)
    taught_once = vocabulary.extended(["ここわしのだせやけんです"])
    assert "しのだせやけん" in taught_once.tokenize("ここわしのだせやけんです")
    again = pickle.loads(pickle.dumps(vocabulary))
    assert again == vocabulary and again.tokenize(SENTENCES[0]) == vocabulary.tokenize(SENTENCES[0])
    data = json.loads(json.dumps(seg.to_dict()))
    assert data["segmenter"] == "sudachipy" and data["segmenter_version"].startswith("sudachipy ")
    assert Segmentation.from_dict(data) == seg
    assert "Japanese, segmented with sudachipy" in seg.describe()


def test_language_option(sudachi: None) -> None:
    spaced = ["ここ わ といれ です", "ここ が ごみばこ", "ごみばこ です"] * 2
    assert Vocabulary.from_sentences(spaced, language="ja").segmentation.segments
    assert not Vocabulary.from_sentences(SENTENCES, language="spaced").segmentation.segments
    # "spaced": the writer separated the words; a run is a word, without a warning
    assert Vocabulary.from_sentences(SENTENCES, language="spaced").tokenize(SENTENCES[0]) == [SENTENCES[0]]
    assert Vocabulary.from_sentences(["ここは台所です"] * 3, learn=False).segmentation.lexicon == ()


# ------------------------------------------------------------------------------ Chinese
def test_chinese_is_segmented_with_jieba(jieba: None) -> None:
    sentences = ["这里是厨房", "这是厨房", "厨房在这里", "这里是卧室", "这是卧室", "卧室在这里"] * 2
    vocabulary = Vocabulary.from_sentences(sentences)
    assert vocabulary.segmentation is not None and vocabulary.segmentation.language == "zh"
    assert "厨房" in vocabulary.tokenize("这里是厨房") and "卧室" in vocabulary.words
    assert tokenize("这里是厨房", vocabulary.segmentation)[-1] == "厨房"


# ------------------------------------------------------------------------------ the command line
def _japanese_homes(folder: Path, n_homes: int = 2) -> Path:
    """Plain homes whose taught sentences are Japanese without spaces, three places each."""
    from spco.data.environment import Environment
    from spco.data.plain import write_home

    rng = np.random.default_rng(0)
    places = {"はぎわらけん": (0.0, 0.0), "にしかわけん": (4.0, 0.0), "かいだんまえ": (0.0, 4.0)}
    for h in range(n_homes):
        positions, sentences = [], []
        for name, (x, y) in places.items():
            for k in range(8):
                theta = rng.uniform(-np.pi, np.pi)
                positions.append((x + rng.normal(0, 0.3), y + rng.normal(0, 0.3), np.sin(theta),
                                  np.cos(theta)))
                sentences.append(FRAMES[k % len(FRAMES)].format(name))
        n = len(positions)
        visual = rng.poisson(3.0, size=(n, 16))
        env = Environment(name=f"home{h}", ids=np.arange(n), positions=np.array(positions), visual=visual,
                          sentences=tuple(sentences), is_test=np.zeros(n, dtype=bool))
        write_home(env, folder / f"home{h}")
    return folder


def test_fit_records_the_segmentation_for_adapt_where_and_teach(sudachi: None, tmp_path: Path) -> None:
    from spco.cli import main
    from spco.knowledge import load_home_model, load_knowledge

    homes = _japanese_homes(tmp_path / "homes")
    runner = CliRunner()
    knowledge = tmp_path / "k.spco"
    result = runner.invoke(main, ["fit", "--data", str(homes), "--iterations", "5", "--model", "spcotransfer",
                                  "--out", str(knowledge)])
    assert result.exit_code == 0, result.output
    assert "text written without spaces: Japanese, segmented with sudachipy" in result.output
    loaded = load_knowledge(knowledge)
    assert loaded.vocabulary.segmentation is not None and "はぎわらけん" in loaded.vocabulary.words
    with np.load(knowledge, allow_pickle=False) as archive:
        header = json.loads(archive["header"].tobytes().decode("utf-8"))
    assert header["format_version"] == 3 and header["segmentation"]["language"] == "ja"
    home = tmp_path / "h.spco"
    result = runner.invoke(main, ["adapt", str(knowledge), "--home", str(homes / "home0"),
                                  "--iterations", "5", "--out", str(home)])
    assert result.exit_code == 0, result.output
    assert load_home_model(home).vocabulary.segmentation == loaded.vocabulary.segmentation
    result = runner.invoke(main, ["where", str(home), "はぎわらけん", "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["name"] == "はぎわらけん"
    result = runner.invoke(main, ["teach", str(home), "--x", "8", "--y", "8", "--theta", "0",
                                  "--sentence", "ここわしのだせやけんです", "--visual", str(_view(tmp_path))])
    assert result.exit_code == 0, result.output
    assert "しのだせやけん" in load_home_model(home).vocabulary.words
    result = runner.invoke(main, ["inspect", str(home)])
    assert result.exit_code == 0 and "text written without spaces: Japanese" in result.output
    result = runner.invoke(main, ["fit", "--data", str(homes), "--iterations", "2",
                                  "--text-language", "spaced", "--out", str(tmp_path / "k2.spco")])
    assert result.exit_code == 0, result.output
    assert not load_knowledge(tmp_path / "k2.spco").vocabulary.segmentation.segments


def _view(folder: Path) -> Path:
    path = folder / "view.npy"
    np.save(path, np.full(16, 3, dtype=np.int64))
    return path


def test_maps_warn_once_without_a_font_for_such_names(monkeypatch: pytest.MonkeyPatch,
                                                      tmp_path: Path) -> None:
    import spco.plots as plots

    monkeypatch.setattr(plots, "_installed_cjk_fonts", lambda: ())
    with pytest.warns(UserWarning) as caught:
        plots.plot_accuracy_curve([0, 1], {"台所": [0.2, 0.4], "お風呂": [0.1, 0.3]}, None, 0.1, "homes",
                                  "ダイニング", path=tmp_path / "curve.png")
    messages = [str(w.message) for w in caught]
    assert sum("install one" in m for m in messages) == 1
    assert not any("missing from font" in m for m in messages)
