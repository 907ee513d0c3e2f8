"""Every deliberate error of grace_dsl is a GraceError (docs/api.md), including those raised below
the runtime: the geometry kernel's and the native code generator's."""

from __future__ import annotations

import casadi as ca
import pytest

import grace_dsl as eac
from grace_dsl import errors, geometry
from grace_dsl.compiler import native
from grace_dsl.runtime import errors as runtime_errors


def test_one_root_re_exported_by_the_runtime() -> None:
    assert runtime_errors.GraceError is errors.GraceError is eac.GraceError


def test_geometry_errors_are_grace_errors_and_still_value_errors() -> None:
    with pytest.raises(eac.GraceError, match="unknown primitive 'Cubiod'") as info:
        geometry.validate("Cubiod", {})
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, geometry.GeometryError)


def test_native_unsupported_is_a_grace_error() -> None:
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    fn = ca.Function("free", [x], [x + y], {"allow_free": True})  # y is never an input
    with pytest.raises(eac.GraceError, match="free variables") as info:
        native.generate_c(fn, "free")
    assert isinstance(info.value, native.NativeUnsupportedError)
    assert isinstance(info.value, ValueError)
