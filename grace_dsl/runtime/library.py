"""Load compiled units as a ``Library`` of ``Concept`` objects (the public runtime entry).

A ``Concept`` exposes its schema (params, grasps, actions, joints, links, doc) from the manifest
and evaluates its functions through the fastest evaluator available, loaded on first use.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

import casadi
import numpy as np

from grace_dsl.compiler import native
from grace_dsl.compiler.build import BuildResult, Progress, build
from grace_dsl.compiler.unit import KEY, UNIT_FORMAT, Unit, UnitError, load_unit, unit_evaluators
from grace_dsl.lang.diagnostics import render_all
from grace_dsl.runtime.concept import ParamPacker, ParamSpec, suggest
from grace_dsl.runtime.errors import CompileError, UnknownNameError
from grace_dsl.runtime.inputs import merge_names
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.specs import ActionSpec, GraspSpec, JointSpec, LinkSpec, PartSpec


class _UnitFunctions:
    """The evaluators of one unit, deserialized and loaded once, on first use."""

    def __init__(self, unit: Unit):
        self.unit = unit
        self._evaluators: dict[str, native.Evaluator] | None = None
        self._symbolic: dict[str, casadi.Function] | None = None

    def get(self, name: str) -> native.Evaluator:
        if self._evaluators is None:
            self._evaluators = dict(unit_evaluators(self.unit))
        return self._evaluators[name]

    def symbolic(self, name: str) -> casadi.Function:
        """The CasADi function itself (deserialized once per unit), for callers that compose
        it into a larger graph and differentiate it (perception's model fit)."""
        if self._symbolic is None:
            data = json.loads((self.unit.dir / "functions.json").read_text(encoding="utf-8"))
            self._symbolic = {n: casadi.Function.deserialize(s) for n, s in data.items()}
        return self._symbolic[name]


class Concept:
    """A compiled concept; ``instantiate`` it with parameter values to get an ``Instance``.

    ``grasps``, ``actions`` and ``joints`` map names to typed specs (``GraspSpec``...), built once
    from the manifest; a spec still reads like the manifest entry (``spec["link"]``)."""

    def __init__(self, entry: Mapping[str, Any], functions: _UnitFunctions):
        self.entry = entry
        self._functions = functions
        self.name: str = entry["name"]
        self.doc: str = entry["doc"]
        self.params: tuple[ParamSpec, ...] = tuple(ParamSpec.from_entry(p) for p in entry["params"])
        self.grasps: Mapping[str, GraspSpec] = MappingProxyType(
            {g["name"]: GraspSpec.of(g, entry) for g in entry["grasps"]}
        )
        self.actions: Mapping[str, ActionSpec] = MappingProxyType(
            {a["name"]: ActionSpec.of(a, entry) for a in entry["actions"]}
        )
        self.joints: Mapping[str, JointSpec] = MappingProxyType(
            {j["name"]: JointSpec.of(j, entry) for j in entry["joints"]}
        )
        self.links: tuple[str, ...] = tuple(link["name"] for link in entry["links"])
        self.link_specs: Mapping[str, LinkSpec] = MappingProxyType(
            {k["name"]: LinkSpec(k["name"], k.get("doc", "")) for k in entry["links"]}
        )
        self.parts: Mapping[str, str] = MappingProxyType(dict(entry["parts"]))
        self.part_specs: Mapping[str, PartSpec] = MappingProxyType(
            {n: PartSpec(n, c) for n, c in entry["parts"].items()}
        )
        moving = sorted((j for j in self.joints.values() if j.moving), key=lambda j: j.index or 0)
        self.moving_joints: tuple[str, ...] = tuple(j.name for j in moving)
        self.joint_index: Mapping[str, int] = MappingProxyType(
            {n: i for i, n in enumerate(self.moving_joints)}
        )
        self._packer = ParamPacker.of(self.params)
        # ranges="valid": no typical range, the domain is checked afterwards (check_domain)
        self._valid_packer = ParamPacker.of(tuple(s.unbounded() for s in self.params))
        self._evaluators: dict[str, native.Evaluator] = {}  # key -> evaluator, on first use

    def __repr__(self) -> str:
        return f"<Concept {self.name}: {len(self.params)} params, {len(self.grasps)} grasps>"

    def function(self, kind: str, name: str = "") -> native.Evaluator:
        """The evaluator of function ``kind:name`` (see docs/architecture.md); prefer the typed
        queries of ``Instance`` and ``grace_dsl.runtime.kinematics.Kinematics``."""
        key = f"{kind}:{name}" if name else kind
        try:
            return self._evaluators[key]
        except KeyError:
            pass
        try:
            evaluator = self._functions.get(self.entry["functions"][key])
        except KeyError:
            raise UnknownNameError(f"{self.name} has no {kind} {name!r}") from None
        self._evaluators[key] = evaluator
        return evaluator

    def symbolic(self, kind: str, name: str = "") -> casadi.Function:
        """The CasADi function behind ``function(kind, name)``: same inputs and outputs, for
        composing and differentiating (``function`` is the fast way to evaluate it)."""
        key = f"{kind}:{name}" if name else kind
        try:
            return self._functions.symbolic(self.entry["functions"][key])
        except KeyError:
            raise UnknownNameError(f"{self.name} has no {kind} {name!r}") from None

    def defaults(self) -> dict[str, Any]:
        return {
            p.name: p.default if p.kind != "choice" else p.decode(np.atleast_1d(p.default))
            for p in self.params
        }

    def pack(self, params: Mapping[str, Any] | None = None, /, **values: Any) -> np.ndarray:
        """The flat SI parameter vector of ``params``/``values`` (defaults for the rest)."""
        return self._packer.pack(merge_names("params", params, values), self.name)

    def instantiate(
        self,
        /,
        pose: Any = None,
        joints: Mapping[str, Any] | None = None,
        params: Mapping[str, Any] | None = None,
        ranges: str = "typical",
        **values: Any,
    ) -> Instance:
        """An instance at ``pose`` (4x4, world from concept) with joint values and parameters.

        Parameters are keywords, or the mapping ``params`` (which also carries names that are
        arguments here: a parameter called ``pose``, ``joints``, ``params`` or ``ranges``).
        ``ranges="typical"`` (the default) keeps every parameter inside its declared range, the
        real-world spread the library is verified over; ``ranges="valid"`` accepts any value
        whose instance is still well-formed (docs/language.md, "Typical and valid values")."""
        return Instance.create(
            self, pose, joints, merge_names("params", params, values), ranges=ranges
        )


class Library(Mapping[str, Concept]):
    """Every concept of a build, by name."""

    def __init__(self, units: Sequence[Unit], result: BuildResult | None = None):
        self.result = result
        self._concepts: dict[str, Concept] = {}
        for unit in units:
            functions = _UnitFunctions(unit)
            for name, entry in unit.concepts.items():
                self._concepts[name] = Concept(entry, functions)

    def __getitem__(self, name: str) -> Concept:
        if not isinstance(name, str):
            raise UnknownNameError(
                f"concept names are strings, not {type(name).__name__} {name!r:.60}"
            )
        try:
            return self._concepts[name]
        except KeyError:
            raise UnknownNameError(
                f"no concept {name!r} in the library" + suggest(name, self._concepts)
            ) from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._concepts)

    def __len__(self) -> int:
        return len(self._concepts)


def compile_paths(
    paths: Sequence[str | Path],
    cache_dir: Path | None = None,
    search_path: Sequence[str | Path] = (),
    progress: Progress | None = None,
) -> Library:
    """Compile .eac files or directories (and what they import) into a ``Library``.

    Raises ``CompileError`` carrying every diagnostic when the sources have errors.
    ``progress(file, done, total)`` is called as each file that was not cached is compiled.
    """
    result = build(paths, cache_dir, search_path, progress=progress)
    if not result.ok:
        raise CompileError(render_all(result.diagnostics, result.sources), result.diagnostics)
    return Library(result.units, result)


def load_library(cache_dir: Path | None = None, progress: Progress | None = None) -> Library:
    """The standard concept library, compiled once and cached."""
    from grace_dsl.compiler.resolve import stdlib_dir

    return compile_paths([stdlib_dir()], cache_dir, progress=progress)


def load_artifact(directory: str | Path) -> Library:
    """A library from an artifact directory written by ``eacc build -o DIR``.

    Loading an artifact runs its native code, so it is checked like the cache: its manifest's
    format, unit names that are keys (no ``../``) resolving inside ``DIR/units``, every unit
    private and intact (``grace_dsl.compiler.unit.verify``). Raises ``UnitError`` otherwise.
    """
    root = Path(directory).resolve()
    try:
        manifest = json.loads((root / "manifest.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise UnitError(f"{root}: no readable manifest.json ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != UNIT_FORMAT:
        found = manifest.get("format") if isinstance(manifest, dict) else None
        raise UnitError(
            f"{root}: artifact format {found!r}, this grace_dsl reads {UNIT_FORMAT}; "
            "rebuild it with `eacc build -o`"
        )
    keys = manifest.get("units")
    if not isinstance(keys, dict):
        raise UnitError(f"{root}: manifest.json lists no units")
    return Library([load_unit(_unit_dir(root, key)) for key in keys])


def _unit_dir(root: Path, key: object) -> Path:
    """``root/units/key``, refused unless ``key`` is a unit key that stays inside ``root``."""
    units = root / "units"
    if not isinstance(key, str) or not KEY.match(key):
        raise UnitError(f"{root}: manifest.json names a unit {key!r} that is not a unit key")
    unit_dir = (units / key).resolve()
    if unit_dir.parent != units.resolve():
        raise UnitError(f"{root}: unit {key} lies outside the artifact ({unit_dir})")
    return unit_dir
