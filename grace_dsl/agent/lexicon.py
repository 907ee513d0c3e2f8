"""The offline parser's vocabulary, built from the prompt catalog.

Nouns come from the catalog: each concept's name split into words (``ChestOfDrawers`` -> "chest
of drawers"), the head of its synopsis ("A microwave oven: ..." -> "microwave oven") and the
alternatives it lists in brackets, its link and part names (``drawer1`` -> "drawer"). Verbs come
from its action names (``turn_on`` -> "turn on"). Where the catalog is silent a small table of
everyday words fills in (``SYNONYMS``: "fridge" is a refrigerator, "cupboard" a cabinet), and
link names that are not everyday words are given one (``LINK_WORDS``: a ``leaf`` is a door).

Words the lexicon does not know are corrected only when exactly one known word is close
(``correct``); otherwise the parser says it does not know them.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

# everyday words for a concept or a part, where the catalog does not use them
SYNONYMS: Mapping[str, tuple[str, ...]] = {
    "fridge": ("refrigerator",),
    "freezer": ("chest freezer",),
    "cupboard": ("cabinet",),
    "dresser": ("chest of drawers",),
    "chest": ("chest of drawers",),
    "commode": ("chest of drawers",),
    "closet": ("wardrobe",),
    "armoire": ("wardrobe",),
    "toilet": ("cistern",),
    "loo": ("cistern",),
    "washer": ("washing machine",),
    "microwave oven": ("microwave",),
    "medicine cabinet": ("mirror cabinet",),
    "mirror": ("mirror cabinet",),
    "bin": ("trash can",),
    "cabinet": ("cabinet",),
}
# a link's name -> the word people use for it
LINK_WORDS: Mapping[str, tuple[str, ...]] = {
    "leaf": ("door",),
    "cover": ("lid",),
    "arm": ("lever",),
    "cap": ("button",),
    "lever": ("lever", "handle"),
    "tray": ("tray",),
    "sash": ("window",),
}
# generic intents: the unit's opening or closing action
OPEN_WORDS = ("open", "pull open", "pull out", "pull", "slide open", "swing open", "lift", "raise")
CLOSE_WORDS = ("close", "shut", "push shut", "push closed", "push in", "push", "slide shut")
SELECTORS: Mapping[str, str] = {
    "top": "top", "upper": "top", "uppermost": "top", "topmost": "top", "highest": "top",
    "bottom": "bottom", "lower": "bottom", "lowest": "bottom", "bottommost": "bottom",
    "left": "left", "leftmost": "left", "left-hand": "left",
    "right": "right", "rightmost": "right", "right-hand": "right",
    "middle": "middle", "centre": "middle", "center": "middle", "central": "middle",
}  # fmt: skip
ORDINALS: Mapping[str, int] = {
    "first": 1, "1st": 1, "second": 2, "2nd": 2, "third": 3, "3rd": 3, "fourth": 4, "4th": 4,
    "last": -1,
}  # fmt: skip
NUMBER_WORDS: Mapping[str, float] = {
    "five": 5, "ten": 10, "fifteen": 15, "twenty": 20, "thirty": 30, "forty": 40,
    "forty-five": 45, "fifty": 50, "sixty": 60, "seventy": 70, "eighty": 80, "ninety": 90,
}  # fmt: skip
UNITS: Mapping[str, tuple[str, float]] = {
    "degree": ("angle", 0.017453292519943295), "degrees": ("angle", 0.017453292519943295),
    "deg": ("angle", 0.017453292519943295), "°": ("angle", 0.017453292519943295),
    "rad": ("angle", 1.0), "radians": ("angle", 1.0),
    "cm": ("length", 0.01), "centimetres": ("length", 0.01), "centimeters": ("length", 0.01),
    "mm": ("length", 0.001), "millimetres": ("length", 0.001), "millimeters": ("length", 0.001),
    "m": ("length", 1.0), "metres": ("length", 1.0), "meters": ("length", 1.0),
    "percent": ("fraction", 0.01), "%": ("fraction", 0.01),
}  # fmt: skip
AMOUNT_PHRASES: Mapping[str, str] = {
    "halfway": "half", "half way": "half", "half-way": "half", "half": "half",
    "all the way": "full", "fully": "full", "completely": "full", "wide": "full",
    "wide open": "full", "a bit": "bit", "a little": "bit", "a little bit": "bit",
    "slightly": "bit", "a touch": "bit",
}  # fmt: skip
SEQUENCE_WORDS = ("and then", "after that", "afterwards", "then", "and", "next", "finally")
PRONOUNS = ("it", "them", "that one", "this one")
QUANTIFIERS = ("all", "every", "each", "both", "all of")
FUNCTION_WORDS = frozenset(
    "the a an of to on in at its by please then and robot can you could would kindly now "
    "first-of-all also from with for one ones way more further".split()
)
FILLERS = frozenset("please kindly now gently carefully slowly quickly just again".split())


def words_of(name: str) -> str:
    """``ChestOfDrawers`` -> "chest of drawers"; ``hall_door`` -> "hall door"."""
    spaced = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", " ", name).replace("_", " ")
    return " ".join(re.sub(r"\d+", " ", spaced).lower().split())


def singular(word: str) -> str:
    """A plural's singular, the way furniture words make them."""
    if word.endswith("ies"):
        return word[:-3] + "y"
    if word.endswith(("ches", "shes", "xes")):
        return word[:-2]
    if word.endswith("s") and not word.endswith("ss"):
        return word[:-1]
    return word


def synopsis_nouns(doc: str) -> list[str]:
    """The noun phrases a synopsis opens with: "A microwave oven: ..." -> ["microwave oven"];
    bracketed alternatives ("(storage box, chest, jewellery box)") are kept too."""
    flat = " ".join(doc.split())
    head = re.split(r"[:;,.(]| with | whose | on | that | of boards", flat, maxsplit=1)[0]
    head = re.sub(r"^(a|an|the)\s+", "", head.strip(), flags=re.I).lower()
    out = [head] if 0 < len(head.split()) <= 4 else []
    first = re.split(r"(?<=[.!?])\s", flat, maxsplit=1)[0]
    for group in re.findall(r"\(([^)]*)\)", first.split(":")[0]):
        out += [w.strip().lower() for w in group.split(",") if 0 < len(w.split()) <= 3]
    clean = [re.sub(r"[^a-z -]", "", o).strip() for o in out if o]
    verbs = set(OPEN_WORDS) | set(CLOSE_WORDS) | set(SELECTORS)
    return [o for o in clean if o and not verbs & set(o.split())]


def part_words(path: str) -> set[str]:
    """The words of a part path or link name: ``drawer[0][1].drawer`` -> {"drawer"},
    ``leaf`` -> {"leaf", "door"}."""
    out: set[str] = set()
    for piece in re.split(r"[.\[\]]", path):
        w = words_of(piece)
        if not w or w.isdigit():
            continue
        out.add(w)
        out.update(LINK_WORDS.get(w, ()))
        for token in w.split():
            out.add(token)
            out.update(LINK_WORDS.get(token, ()))
    return out


@dataclass(frozen=True)
class Lexicon:
    """Every phrase the parser knows, by role."""

    concept_nouns: Mapping[str, frozenset[str]]  # phrase -> concepts it names
    part_nouns: frozenset[str]
    action_phrases: frozenset[str]  # "turn on", "flush": a concept's own action names
    phrases: tuple[str, ...] = field(default=())  # every multi-word phrase, longest first
    words: frozenset[str] = field(default=frozenset())  # every single word known

    @classmethod
    def from_library(cls, lib: Any) -> Lexicon:
        """The lexicon of a library's catalog: the same synopses, links, parts and actions as
        ``build_catalog`` gives, read without its grasp formulas (which take seconds)."""
        concepts = [
            {
                "name": c.name,
                "kind": c.entry["kind"],
                "doc": c.doc,
                "links": [dict(link) for link in c.entry["links"]],
                "parts": [{"name": p} for p in c.parts],
                "actions": [{"name": a["name"], "joint": a["joint"]} for a in c.actions.values()],
            }
            for c in (lib[name] for name in lib)
        ]
        return cls.from_catalog({"categories": [{"concepts": concepts}]})

    @classmethod
    def from_catalog(cls, catalog: Mapping[str, Any]) -> Lexicon:
        """The lexicon of a catalog (``grace_dsl.agent.catalog.build_catalog``)."""
        nouns: dict[str, set[str]] = {}
        parts: set[str] = set()
        actions: set[str] = set()
        for cat in catalog["categories"]:
            for c in cat["concepts"]:
                if c["kind"] == "primitive":
                    continue
                for phrase in concept_phrases(c):
                    nouns.setdefault(phrase, set()).add(c["name"])
                for link in c["links"]:
                    parts |= part_words(link["name"])
                for p in c["parts"]:
                    parts |= part_words(p["name"])
                for a in c["actions"]:
                    if a["joint"]:
                        actions.add(words_of(a["name"].rsplit(".", 1)[-1]))
        for word, targets in SYNONYMS.items():
            named = set().union(*(nouns.get(t, set()) for t in targets))
            if named:
                nouns.setdefault(word, set()).update(named)
        parts.discard("base")
        return cls.make({k: frozenset(v) for k, v in nouns.items()}, frozenset(parts), actions)

    @classmethod
    def make(
        cls,
        nouns: Mapping[str, frozenset[str]],
        parts: frozenset[str],
        actions: Iterable[str],
    ) -> Lexicon:
        actions = frozenset(actions)
        every = (
            set(nouns) | parts | actions | set(OPEN_WORDS) | set(CLOSE_WORDS)
            | set(SELECTORS) | set(ORDINALS) | set(AMOUNT_PHRASES) | set(SEQUENCE_WORDS)
            | set(PRONOUNS) | set(UNITS) | set(NUMBER_WORDS) | set(QUANTIFIERS)
        )  # fmt: skip
        phrases = tuple(sorted((p for p in every if " " in p), key=lambda p: -len(p.split())))
        words = {w for p in every for w in p.split()} | FILLERS
        words |= {w + "s" for w in parts | set(nouns) if " " not in w}
        words -= FUNCTION_WORDS - FILLERS  # a misspelling is corrected to a word that matters
        return cls(nouns, parts, actions, phrases, frozenset(words))

    def correct(self, word: str) -> tuple[str | None, tuple[str, ...]]:
        """A misspelt word's correction: (the word, ()) when exactly one known word is nearest
        (one edit for words of 4 to 6 letters, two from 7; a swap of neighbours is one edit),
        (None, the nearest) otherwise. Words under 4 letters are never corrected."""
        return nearest(word, self.words)


def nearest(word: str, known: Iterable[str]) -> tuple[str | None, tuple[str, ...]]:
    """``Lexicon.correct`` over any set of words."""
    if len(word) < 4 or not word.isalpha():
        return None, ()
    budget = 1 if len(word) < 7 else 2
    scored = [(edits(word, k), k) for k in known if abs(len(k) - len(word)) <= budget]
    close = sorted((d, k) for d, k in scored if d <= budget)
    if not close:
        return None, ()
    best = [k for d, k in close if d == close[0][0]]
    return (best[0], ()) if len(best) == 1 else (None, tuple(best))


def edits(a: str, b: str) -> int:
    """The optimal-string-alignment distance: insertions, deletions, substitutions and swaps of
    neighbouring letters, one edit each."""
    d = [[i + j if i * j == 0 else 0 for j in range(len(b) + 1)] for i in range(len(a) + 1)]
    for i in range(1, len(a) + 1):
        for j in range(1, len(b) + 1):
            cost = a[i - 1] != b[j - 1]
            d[i][j] = min(d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost)
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                d[i][j] = min(d[i][j], d[i - 2][j - 2] + 1)
    return d[len(a)][len(b)]


def concept_phrases(c: Mapping[str, Any]) -> set[str]:
    """The noun phrases that name concept ``c``: its name's words, its synopsis head and
    bracketed alternatives, and the last word of each (the head noun)."""
    out = {words_of(c["name"])}
    out.update(w for w in words_of(c["name"]).split() if w != "of")
    out.update(synopsis_nouns(c["doc"]))
    for phrase in list(out):
        words = phrase.split()
        if "of" in words:  # "chest of drawers": the head is "chest"
            out.add(words[0])
        elif words:
            out.add(words[-1])
            if len(words) > 2:
                out.add(" ".join(words[-2:]))
    return {o for o in out if o and o not in FUNCTION_WORDS and len(o) > 2}
