"""What a stage of the estimate says about itself: entries for the profile's ``meta`` and one-line warnings. Each
stage returns its own record beside its result, and the stage that called it composes them, so no stage writes
into another's dictionary and a reading can be followed back to the stage that made it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class Findings:
    """A stage's entries for the profile's ``meta`` and its warnings (one line each, naming the reference)."""

    meta: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def include(self, other: Findings) -> None:
        """Take a called stage's findings into this record (its entries replace any of the same name)."""
        self.meta |= other.meta
        self.warnings += other.warnings
