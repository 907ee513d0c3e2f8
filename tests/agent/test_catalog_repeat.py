"""The prompt catalog of a concept with a ``for`` loop and a variant part: indexed names, the
repeated members with their counts, the variant lists, and no values at the defaults for copies
the defaults leave out."""

from __future__ import annotations

from typing import Any

import pytest

from grace_dsl.agent.catalog import build_catalog, render_markdown
from grace_dsl.compiler.build import build
from grace_dsl.runtime.library import Library
from tests.runtime.conftest import STACK as SOURCE

pytestmark = pytest.mark.slow  # one compile (CasADi's VM, no C)


@pytest.fixture(scope="module")
def catalog(tmp_path_factory: pytest.TempPathFactory) -> Any:
    root = tmp_path_factory.mktemp("stack")
    (root / "stack.eac").write_text(SOURCE, encoding="utf-8")
    result = build([root / "stack.eac"], root / "cache", use_native=False)
    assert result.ok, result.diagnostics
    return build_catalog(Library(result.units, result), ["Stack"])


def _stack(catalog: Any) -> Any:
    (cat,) = catalog["categories"]
    (concept,) = cat["concepts"]
    return concept


def test_repeats_and_variants(catalog: Any) -> None:
    c = _stack(catalog)
    assert c["repeats"]["drawer"] == {"indices": ["[0]", "[1]", "[2]", "[3]"], "counts": ["n"]}
    assert c["repeats"]["slide"]["counts"] == ["n"]
    assert "body" not in c["repeats"] and "handle" in c["repeats"]
    assert c["variants"]["handle[2]"] == {
        "param": "kind",
        "options": {"bar": "StraightHandle", "ring": "RingPull"},
        "parts": {"bar": "handle[2]@bar", "ring": "handle[2]@ring"},
    }


def test_indexed_members_keep_their_sources(catalog: Any) -> None:
    c = _stack(catalog)
    joints = {j["name"]: j for j in c["joints"]}
    assert joints["slide[1]"]["axis"] == "(0, 0, 1)"
    assert joints["slide[1]"]["limits"] == [0.0, 0.25]
    assert joints["slide[3]"]["limits"] is None  # the defaults (n = 3) have no drawer 3
    grasps = {g["name"]: g for g in c["grasps"]}
    assert grasps["handle[1]@bar.pull"]["free"][0]["at_defaults"] is not None
    assert grasps["handle[1]@ring.pull"]["free"][0]["at_defaults"] is None  # kind is "bar"
    parts = {p["name"]: p for p in c["parts"]}
    assert parts["handle[1]@bar"]["link"] == "drawer[1]"
    assert parts["handle[1]@bar"]["at"] == "trans(0, i * h, 200mm)"


def test_markdown_lists_repeats_and_variants(catalog: Any) -> None:
    text = render_markdown(catalog)
    assert "- `drawer`: indices [0], [1], [2], [3], as many as `n` says" in text
    assert '- `handle[0]` by `kind`: "bar" → StraightHandle (`handle[0]@bar`)' in text
