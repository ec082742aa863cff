"""Test helper: a plan's screening answer with one of the fast engine's shortcuts on and off."""

from mcusim.engine import screening


def with_and_without(switch: str, plan, x0, n, extra):
    """(answer with ``screening.<switch>`` on, answer with it off) of ``plan.first_flag``."""
    setattr(screening, switch, False)
    try:
        full = plan.first_flag(x0, n, extra)
    finally:
        setattr(screening, switch, True)
    return plan.first_flag(x0, n, extra), full
