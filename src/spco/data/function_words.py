"""English function words: the closed-class words that are never a place's name.

The tokeniser's term rule (:mod:`spco.data.language`: no closed-class word or number starts a learnt
term, ends it or comes at its join), the names a home learns from a sentence
(:meth:`~spco.data.language.Vocabulary.new_word_runs`), the frames of the name evidence
(:mod:`spco.model.name_evidence`) and the look-up of names nobody said (:mod:`spco.model.unheard`) read
these lists. They are English: in another language none of them occurs.
"""

from __future__ import annotations

#: Determiners and possessive pronouns (a word ending in "'s" or "s'" also counts as a possessive).
DETERMINERS = frozenset({"the", "a", "an", "this", "that", "these", "those", "my", "our", "your", "his",
                         "her", "their", "its", "whose"})
#: Words that may lead a place name asked for without being part of it ("the kitchen", "my room",
#: "our study"): an article or a possessive pronoun of the speaker or listener
#: (:meth:`~spco.data.language.Vocabulary.query` drops one when other words follow; the
#: configuration files compare names the same way).
NAME_LEADING_WORDS = ("the", "a", "an", "my", "our", "your")
#: Prepositions (place and direction phrases: "on the table", "to your left", "next to the bath").
PREPOSITIONS = frozenset({"to", "in", "on", "at", "by", "from", "into", "onto", "near", "next", "beside",
                          "behind", "under", "over", "across", "through", "after", "before", "for",
                          "with", "of", "off", "out", "up", "down", "around", "between", "inside",
                          "outside", "past", "toward", "towards", "along", "against", "opposite",
                          "above", "below", "beneath", "underneath", "within", "without", "via"})
#: Copulas and naming verbs: what comes before a name in "this is X", "we call it X".
COPULAS = frozenset({"is", "are", "was", "it's", "that's", "here's", "this's", "called", "call",
                     "named", "name", "be", "it", "s"})
#: Personal pronouns (subjects and objects: "I'm home", "we eat", "see you").
PRONOUNS = frozenset({"i", "i'm", "me", "we", "we're", "us", "you", "you're", "he", "she", "they",
                      "they're", "him", "them", "i've", "we've", "i'll", "we'll"})
#: Other closed-class words: conjunctions, auxiliaries and their contractions, negations, question
#: words, adverbs of place and fillers. With the lists above: words that are never a place's name
#: (:func:`spco.model.name_evidence.content_share`).
OTHER_FUNCTION_WORDS = frozenset({
    "and", "or", "but", "so", "if", "then", "than", "because", "as", "do", "does", "did", "don't",
    "doesn't", "didn't", "can", "can't", "cannot", "could", "will", "won't", "would", "should", "shall",
    "may", "might", "must", "have", "has", "had", "having", "been", "being", "am", "were", "isn't",
    "aren't", "wasn't", "weren't", "not", "no", "yes", "yeah", "ok", "okay", "um", "uh", "er", "hmm",
    "oh", "ah", "well", "like", "just", "also", "too", "very", "really", "here", "there", "where",
    "what", "which", "who", "when", "how", "why", "all", "some", "any", "every", "each", "much",
    "many", "more", "most", "again", "ago", "about", "always", "never", "now", "only", "still",
    "it'll", "that'll", "there's", "what's", "where's", "let's", "she's", "he's", "you'll", "you've",
    "they'll", "they've", "i'd", "we'd", "you'd", "let", "get", "got", "go", "going", "gonna",
    "wanna", "please", "thanks", "thank", "hi", "hello", "hey", "bye", "robot", "one", "ones"})

#: Every closed-class word spco knows (English): :data:`DETERMINERS`, :data:`PREPOSITIONS`,
#: :data:`COPULAS`, :data:`PRONOUNS` and :data:`OTHER_FUNCTION_WORDS`.
CLOSED_CLASS = DETERMINERS | PREPOSITIONS | COPULAS | PRONOUNS | OTHER_FUNCTION_WORDS


def is_function_word(token: str) -> bool:
    """Whether one token is a closed-class word or a number ("2", "11", "2am", "1st")."""
    return token in CLOSED_CLASS or (any(ch.isdigit() for ch in token) and len(token) <= 6)


#: Words a name taught once may start with although they are function words
#: (:meth:`spco.data.language.Vocabulary.new_word_runs`; not a learnt term, rule 4b of
#: :mod:`spco.data.language`): possessive determiners ("my room", "our bedroom").
NAME_OPENERS = frozenset({"my", "our", "your", "his", "her", "their"})
