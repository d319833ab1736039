"""Uncertain parameters, the physical human model and parametric families."""

__all__: list[str] = []
