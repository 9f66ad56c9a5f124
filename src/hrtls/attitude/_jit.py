"""Compile options shared by the attitude kernels."""

from __future__ import annotations

from typing import Any

FASTMATH = {"reassoc", "contract", "arcp", "nsz"}
"""LLVM fast-math flags of the kernels: reassociation and fused multiply-add, but NaN and inf
keep their IEEE meaning (the gates test for them)."""
JIT: dict[str, Any] = {"cache": True, "fastmath": FASTMATH, "error_model": "numpy"}
"""Options of every compiled attitude kernel."""
