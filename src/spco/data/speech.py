"""Free-form sentences for synthetic homes: people talking as people do (``language="free"``).

The paper's five templates ("this is the X") make naming easy. Real users say "we're in the living
room now", "by the fridge", "um this is where we eat dinner", call the bath "bathroom" or "shower",
make typos, and sometimes name the room next door. :class:`Household` imitates that:

- *Names and synonyms.* Every place type has several names (:data:`PLACE_WORDS`: the bath is "bath",
  "bathroom", "shower" or "bathtub"), many of them multi-word ("living room", "front door"). A
  household prefers some names over others (Dirichlet around the lexicon's weights), and each person
  has a favourite name per place that they use with their own loyalty.
- *Objects and activities instead of names.* With a personal rate a person names something at the
  place ("by the fridge", "next to the washing machine") or what is done there ("this is where we eat
  dinner"), not the place.
- *Phrasing habits.* Each person uses a few favourite frames out of :data:`NAME_FRAMES`; fillers
  ("um", "hey robot", "you know") and capitals and punctuation vary per person.
- *Typos.* With a personal rate a word of four or more letters gets one typo (two letters swapped,
  one dropped or doubled).
- *Neighbouring places.* With the household's rate a sentence names a room next door ("the kitchen is
  just over there") instead of the place where the robot is.

Households have one to three people; each taught sample is said by one of them. The ground truth of
such a home lists, for each place, its *accepted names* (:func:`accepted_names`: the lexicon's names
of the place), so that a model which answers "bathroom" at the bath is right.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from spco.data.language import normalize_name

__all__ = ["NAME_FRAMES", "PLACE_WORDS", "Household", "PlaceWords", "accepted_names", "place_words"]


@dataclass(frozen=True)
class PlaceWords:
    """How people talk about one place type.

    names: the names of the place, commonest first (all of them are accepted answers);
    weights: how common each name is, same length; objects: things seen there ("the fridge");
    activities: what is done there, as a relative clause ("where we cook").
    """

    names: tuple[str, ...]
    weights: tuple[float, ...]
    objects: tuple[str, ...] = ()
    activities: tuple[str, ...] = ()


#: The lexicon of the eight SIGVerse place types (keys are normalised place names).
PLACE_WORDS: dict[str, PlaceWords] = {
    "entrance": PlaceWords(("entrance", "front door", "entryway", "hallway"), (0.4, 0.3, 0.15, 0.15),
                           ("the shoe rack", "the coat hooks", "the doormat"),
                           ("where we take our shoes off", "where guests come in")),
    "living room": PlaceWords(("living room", "lounge", "sitting room", "family room"),
                              (0.55, 0.2, 0.15, 0.1), ("the sofa", "the couch", "the tv"),
                              ("where we watch tv", "where we relax in the evening")),
    "dining": PlaceWords(("dining room", "dining area", "dining"), (0.55, 0.3, 0.15),
                         ("the dining table", "the big table"),
                         ("where we eat dinner", "where we have breakfast")),
    "kitchen": PlaceWords(("kitchen", "kitchenette", "cooking area"), (0.8, 0.1, 0.1),
                          ("the fridge", "the stove", "the oven", "the microwave"),
                          ("where we cook", "where i make coffee")),
    "bedroom": PlaceWords(("bedroom", "sleeping room"), (0.85, 0.15),
                          ("the bed", "the wardrobe", "the closet"), ("where i sleep", "where we sleep")),
    "bath": PlaceWords(("bath", "bathroom", "shower", "bathtub"), (0.35, 0.35, 0.2, 0.1),
                       ("the tub", "the shower curtain"), ("where we take a bath", "where we shower")),
    "washroom": PlaceWords(("washroom", "laundry room", "utility room"), (0.5, 0.3, 0.2),
                           ("the washing machine", "the sink", "the dryer"),
                           ("where we do the laundry", "where we brush our teeth")),
    "toilet": PlaceWords(("toilet", "restroom", "loo", "wc"), (0.55, 0.2, 0.15, 0.1),
                         ("the toilet paper",), ("where you can wash your hands after",)),
}

#: Phrasings of a sentence naming a place; ``{n}`` is the name.
NAME_FRAMES: tuple[str, ...] = (
    "this is the {n}", "this is our {n}", "here is the {n}", "we're in the {n} now", "ok this is the {n}",
    "the {n}", "{n}", "this room is the {n}", "you are in the {n}", "welcome to the {n}", "that's the {n}",
    "this would be the {n}", "we call this the {n}", "{n} here", "this part is the {n}",
    "remember this is the {n}", "the {n} is here", "it's the {n}", "in the {n}", "and this is the {n}",
)
#: Phrasings naming an object at the place; ``{o}`` is the object.
OBJECT_FRAMES: tuple[str, ...] = ("by {o}", "next to {o}", "{o} is here", "this is where {o} is",
                                  "near {o}", "right by {o}", "look {o}")
#: Phrasings naming what is done at the place; ``{a}`` is the activity.
ACTIVITY_FRAMES: tuple[str, ...] = ("this is {a}", "here is {a}", "{a}", "this is the spot {a}")
#: Phrasings naming a neighbouring place.
NEIGHBOUR_FRAMES: tuple[str, ...] = ("the {n} is next door", "the {n} is just over there",
                                     "that way is the {n}", "through there is the {n}")
FILLERS: tuple[str, ...] = ("um", "uh", "so", "well", "okay", "hey robot", "you know", "like", "alright",
                            "oh")


def place_words(place: str) -> PlaceWords:
    """The lexicon entry of ``place`` (a place type or a home-specific name such as ``"Emma's-room"``:
    "emma's room", "emma's bedroom"); a place not in :data:`PLACE_WORDS` is called by its name only."""
    key = normalize_name(place)
    if key in PLACE_WORDS:
        return PLACE_WORDS[key]
    words = key.split()
    if len(words) == 2 and words[0].endswith("'s") and words[1] == "room":
        owner = words[0]
        return PlaceWords((key, f"{owner} bedroom"), (0.75, 0.25), (f"{owner} desk", f"{owner} bed"))
    return PlaceWords((key,), (1.0,))


def accepted_names(place: str) -> tuple[str, ...]:
    """The names counted right for ``place`` (normalised; the place's own name first)."""
    key = normalize_name(place)
    return tuple(dict.fromkeys([key, *(normalize_name(n) for n in place_words(place).names)]))


@dataclass
class _Speaker:
    loyalty: float
    object_rate: float
    filler_rate: float
    typo_rate: float
    capitalise: bool
    frames: np.ndarray  # weights over NAME_FRAMES
    favourites: dict[str, int] = field(default_factory=dict)


def _typo(rng: np.random.Generator, sentence: str) -> str:
    words = sentence.split(" ")
    long = [i for i, w in enumerate(words) if len(w) >= 4 and w.isalpha()]
    if not long:
        return sentence
    i = long[int(rng.integers(len(long)))]
    w = words[i]
    j = int(rng.integers(1, len(w) - 1))
    kind = int(rng.integers(3))
    if kind == 0:
        w = w[:j] + w[j + 1] + w[j] + w[j + 2:]
    elif kind == 1:
        w = w[:j] + w[j + 1:]
    else:
        w = w[:j] + w[j] + w[j:]
    words[i] = w
    return " ".join(words)


class Household:
    """The people of one home and their way of talking (see the module docstring).

    Parameters
    ----------
    rng: the home's generator (every draw comes from it).
    neighbour_rate: share of sentences naming a neighbouring place (default: drawn, 0–8 %).
    """

    def __init__(self, rng: np.random.Generator, neighbour_rate: float | None = None) -> None:
        self._rng = rng
        self.neighbour_rate = float(rng.uniform(0.0, 0.08)) if neighbour_rate is None else neighbour_rate
        self._name_weights: dict[str, np.ndarray] = {}
        self.speakers = [self._speaker() for _ in range(int(rng.integers(1, 4)))]

    def _speaker(self) -> _Speaker:
        rng = self._rng
        frames = np.zeros(len(NAME_FRAMES))
        chosen = rng.choice(len(NAME_FRAMES), size=int(rng.integers(3, 8)), replace=False)
        frames[chosen] = rng.dirichlet(np.ones(chosen.size))
        return _Speaker(loyalty=float(rng.uniform(0.3, 0.9)), object_rate=float(rng.uniform(0.0, 0.4)),
                        filler_rate=float(rng.uniform(0.0, 0.4)), typo_rate=float(rng.uniform(0.0, 0.06)),
                        capitalise=bool(rng.random() < 0.5), frames=frames)

    def _weights(self, place: str) -> np.ndarray:
        if place not in self._name_weights:
            base = np.asarray(place_words(place).weights, dtype=np.float64)
            self._name_weights[place] = self._rng.dirichlet(base * 5.0)
        return self._name_weights[place]

    def _name(self, speaker: _Speaker, place: str) -> str:
        rng = self._rng
        words = place_words(place)
        weights = self._weights(place)
        if place not in speaker.favourites:
            speaker.favourites[place] = int(rng.choice(len(words.names), p=weights))
        if rng.random() < speaker.loyalty:
            return words.names[speaker.favourites[place]]
        return words.names[int(rng.choice(len(words.names), p=weights))]

    def sentence(self, place: str, neighbours: Sequence[str] = ()) -> str:
        """What one of the household says at ``place`` (a place type or home-specific name);
        ``neighbours`` are the places next door (one of them may be named instead)."""
        rng = self._rng
        speaker = self.speakers[int(rng.integers(len(self.speakers)))]
        words = place_words(place)
        if neighbours and rng.random() < self.neighbour_rate:
            other = neighbours[int(rng.integers(len(neighbours)))]
            frame = NEIGHBOUR_FRAMES[int(rng.integers(len(NEIGHBOUR_FRAMES)))]
            text = frame.format(n=self._name(speaker, other))
        elif (words.objects or words.activities) and rng.random() < speaker.object_rate:
            pick_object = bool(words.objects) and (not words.activities or rng.random() < 0.6)
            if pick_object:
                text = OBJECT_FRAMES[int(rng.integers(len(OBJECT_FRAMES)))].format(
                    o=words.objects[int(rng.integers(len(words.objects)))])
            else:
                text = ACTIVITY_FRAMES[int(rng.integers(len(ACTIVITY_FRAMES)))].format(
                    a=words.activities[int(rng.integers(len(words.activities)))])
        else:
            frame = NAME_FRAMES[int(rng.choice(len(NAME_FRAMES), p=speaker.frames))]
            text = frame.format(n=self._name(speaker, place))
        if rng.random() < speaker.filler_rate:
            text = f"{FILLERS[int(rng.integers(len(FILLERS)))]} {text}"
        if rng.random() < speaker.typo_rate:
            text = _typo(rng, text)
        if speaker.capitalise:
            text = text[:1].upper() + text[1:]
        end = rng.random()
        return text + ("." if end < 0.2 else "!" if end < 0.3 else "")
