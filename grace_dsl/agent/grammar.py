"""The offline parser's grammar: an instruction -> clauses (one sub-task each).

The rules, in the order they apply:

1. Sequence: the instruction splits into clauses at commas, semicolons, full stops and the
   words "then", "and then", "after that", "afterwards", "next", "finally" and "and". A clause
   without a verb takes the previous clause's ("open the microwave and the fridge").
2. Phrases: within a clause the longest known phrase wins ("chest of drawers", "pull out",
   "all the way", "turn on").
3. Roles: a quantifier ("all", "every", "both": each part that matches); a verb (an opening
   or closing word, or a concept's own action such as "flush"); an amount ("halfway", "all the
   way", "a bit", "by 30 degrees", "to 50 percent", "10 cm"); the selectors top/bottom/left/
   right/middle (and upper, lower, leftmost, ...) and the ordinals first/second/third/last; a
   pronoun ("it"); nouns (concepts, parts, the scene's object names, in order, so "the top
   drawer of the chest" gives the nouns drawer and chest; plurals as their singular); function
   words ("the", "of", "please"), which are dropped.
4. Any other word is corrected when exactly one known word is close to it (the clause notes it);
   otherwise it is reported as unknown and the parser refuses the instruction.
"""

from __future__ import annotations

import re
from collections.abc import Collection
from dataclasses import dataclass

from grace_dsl.agent.lexicon import (
    AMOUNT_PHRASES,
    CLOSE_WORDS,
    FILLERS,
    FUNCTION_WORDS,
    NUMBER_WORDS,
    OPEN_WORDS,
    ORDINALS,
    PRONOUNS,
    QUANTIFIERS,
    SELECTORS,
    UNITS,
    Lexicon,
    nearest,
    singular,
)

_SPLIT = re.compile(r"\s*(?:[,;.]|\b(?:and then|after that|afterwards|then|next|finally|and)\b)\s*")


@dataclass(frozen=True)
class Amount:
    """How far: ``full`` (all the way), ``half``, ``bit`` (a little), ``by`` a measure or ``to``
    a measure; ``dim`` is ``angle`` (rad), ``length`` (m) or ``fraction`` (of the range)."""

    kind: str
    value: float = 0.0
    dim: str | None = None


@dataclass(frozen=True)
class Clause:
    """One clause of an instruction, its words sorted by role."""

    text: str
    verb: str | None = None  # the phrase as written after correction ("open", "turn on")
    intent: str | None = None  # "open", "close" or "action" (a concept's own action name)
    amount: Amount | None = None
    selectors: tuple[str, ...] = ()  # "top", "left", ...
    ordinal: int | None = None  # 1, 2, 3 or -1 (last)
    nouns: tuple[str, ...] = ()
    pronoun: bool = False
    every: bool = False  # "all", "every", "both": each part that matches
    unknown: tuple[str, ...] = ()
    ambiguous: tuple[tuple[str, tuple[str, ...]], ...] = ()  # (word, close known words)
    notes: tuple[str, ...] = ()


def split_clauses(instruction: str) -> list[str]:
    """The instruction's clauses, in order (empty pieces dropped)."""
    text = instruction.strip().lower()
    return [c.strip() for c in _SPLIT.split(text) if c and c.strip()]


def tokens(text: str, lexicon: Lexicon, extra: Collection[str] = ()) -> list[str]:
    """The clause's words joined into the longest known phrases."""
    text = re.sub(r"(\d)(°|%)", r"\1 \2", text)
    text = re.sub(r"(\d)(cm|mm|m|deg|degrees|rad)\b", r"\1 \2", text)
    text = re.sub(r"'s\b", "", text)
    words = [w for w in re.findall(r"[a-z0-9][a-z0-9.\-]*|°|%", text)]
    words = [w.rstrip(".-") for w in words]
    phrases = sorted(
        set(lexicon.phrases) | {p for p in extra if " " in p}, key=lambda p: -len(p.split())
    )
    out: list[str] = []
    i = 0
    while i < len(words):
        for p in phrases:
            n = len(p.split())
            if " ".join(words[i : i + n]) == p:
                out.append(p)
                i += n
                break
        else:
            out.append(words[i])
            i += 1
    return out


def parse_clause(text: str, lexicon: Lexicon, extra: Collection[str] = ()) -> Clause:
    """One clause's roles (rule 3) with misspellings corrected or reported (rule 4)."""
    toks = tokens(text, lexicon, extra)
    known_nouns = set(lexicon.concept_nouns) | set(lexicon.part_nouns) | set(extra)
    verb = intent = None
    amount: Amount | None = None
    selectors: list[str] = []
    ordinal = None
    nouns: list[str] = []
    pronoun = False
    every = False
    unknown: list[str] = []
    ambiguous: list[tuple[str, tuple[str, ...]]] = []
    notes: list[str] = []
    i = 0
    while i < len(toks):
        t = toks[i]
        nxt = toks[i + 1] if i + 1 < len(toks) else ""
        number = _number(t)
        if number is not None and nxt in UNITS:
            dim, scale = UNITS[nxt]
            prev = toks[i - 1] if i else ""
            kind = "by" if prev == "by" else "to"
            amount = Amount(kind, number * scale, dim)
            i += 2
            continue
        role = _role(t, verb is None, lexicon, known_nouns)
        if role is None and t not in FUNCTION_WORDS:
            fixed, close = lexicon.correct(t)
            if fixed is None:
                fixed, close = _correct_in(t, known_nouns, close)
            if fixed is not None:
                notes.append(f"read {t!r} as {fixed!r}")
                t = fixed
                role = _role(t, verb is None, lexicon, known_nouns)
            elif close:
                ambiguous.append((t, close))
            else:
                unknown.append(t)
        if role == "verb":
            verb = t
            intent = "open" if t in OPEN_WORDS else "close" if t in CLOSE_WORDS else "action"
        elif role == "amount":
            amount = Amount(AMOUNT_PHRASES[t])
        elif role == "selector":
            selectors.append(SELECTORS[t])
        elif role == "ordinal":
            ordinal = ORDINALS[t]
        elif role == "pronoun":
            pronoun = True
        elif role == "every":
            every = True
        elif role == "noun":
            nouns.append(singular(t) if singular(t) in known_nouns else t)
        elif role == "filler":
            notes.append(f"ignored {t!r}")
        i += 1
    return Clause(
        text=text,
        verb=verb,
        intent=intent,
        amount=amount,
        selectors=tuple(selectors),
        ordinal=ordinal,
        nouns=tuple(nouns),
        pronoun=pronoun,
        every=every,
        unknown=tuple(unknown),
        ambiguous=tuple(ambiguous),
        notes=tuple(notes),
    )


def _role(t: str, want_verb: bool, lexicon: Lexicon, nouns: Collection[str]) -> str | None:
    """A token's role; a word that is both a verb and a noun ("flush") is a verb first."""
    if want_verb and (t in OPEN_WORDS or t in CLOSE_WORDS or t in lexicon.action_phrases):
        return "verb"
    if t in AMOUNT_PHRASES:
        return "amount"
    if t in SELECTORS:
        return "selector"
    if t in ORDINALS:
        return "ordinal"
    if t in PRONOUNS:
        return "pronoun"
    if t in QUANTIFIERS:
        return "every"
    if t in nouns or singular(t) in nouns:
        return "noun"
    if t in FILLERS:
        return "filler"
    if t in FUNCTION_WORDS:
        return "function"
    if not want_verb and (t in OPEN_WORDS or t in CLOSE_WORDS or t in lexicon.action_phrases):
        return "function"  # a second verb word ("pull it open") adds nothing
    return None


def _correct_in(
    word: str, known: Collection[str], close: tuple[str, ...]
) -> tuple[str | None, tuple[str, ...]]:
    """A correction among the scene's own nouns (object names) when the lexicon found none."""
    if close:
        return None, close
    return nearest(word, {w for w in known if " " not in w})


def _number(t: str) -> float | None:
    if t in NUMBER_WORDS:
        return float(NUMBER_WORDS[t])
    try:
        return float(t)
    except ValueError:
        return None
