"""Undo/redo history of the sketch as immutable snapshots (no Qt).

A :class:`SketchState` is a frozen value: a tuple of :class:`engine.strokes.Stroke`
(themselves read-only) plus an optional background image token. The history keeps one
snapshot per user action, so undo/redo is exact (the eraser splits strokes into new
Stroke objects; the old snapshot still holds the originals). Snapshots share unchanged
Stroke objects, so memory grows with what changed, not with the drawing's size.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from engine.strokes import Stroke


@dataclass(frozen=True, eq=False)
class SketchState:
    """One immutable snapshot of everything drawn.

    Attributes:
        strokes: the strokes, oldest first.
        background: an opaque, immutable background-layer value (the canvas stores a
            read-only (H, W) float32 ink array, 1 = ink) or None.
        label: what produced this state ("stroke", "erase", "clear", ...), for menus.
    """

    strokes: tuple[Stroke, ...] = ()
    background: object | None = None
    label: str = ""

    def __post_init__(self) -> None:
        strokes = tuple(self.strokes)
        for s in strokes:
            if not isinstance(s, Stroke):
                raise TypeError(f"SketchState strokes must be engine.strokes.Stroke, got {type(s).__name__}")
        object.__setattr__(self, "strokes", strokes)

    @property
    def is_empty(self) -> bool:
        """True when there is neither a stroke nor a background layer."""
        return not self.strokes and self.background is None

    def same_content(self, other: SketchState) -> bool:
        """True when both states hold the very same stroke objects and background."""
        return (
            len(self.strokes) == len(other.strokes)
            and all(a is b for a, b in zip(self.strokes, other.strokes))
            and self.background is other.background
        )


@dataclass
class History:
    """Linear undo/redo stack of :class:`SketchState` snapshots, unlimited within a session.

    ``current`` is always valid; ``push`` drops the redo branch. Pushing a state with the
    same content as the current one is ignored (returns False), so no-op actions (an eraser
    pass that hit nothing) create no undo step.
    """

    _states: list[SketchState] = field(default_factory=lambda: [SketchState()])
    _index: int = 0

    @property
    def current(self) -> SketchState:
        return self._states[self._index]

    @property
    def can_undo(self) -> bool:
        return self._index > 0

    @property
    def can_redo(self) -> bool:
        return self._index < len(self._states) - 1

    @property
    def undo_label(self) -> str:
        return self.current.label if self.can_undo else ""

    @property
    def redo_label(self) -> str:
        return self._states[self._index + 1].label if self.can_redo else ""

    def __len__(self) -> int:
        return len(self._states)

    def push(self, state: SketchState) -> bool:
        """Make ``state`` current, discarding any redo states. Returns False for a no-op."""
        if not isinstance(state, SketchState):
            raise TypeError(f"History.push needs a SketchState, got {type(state).__name__}")
        if state.same_content(self.current):
            return False
        del self._states[self._index + 1 :]
        self._states.append(state)
        self._index += 1
        return True

    def undo(self) -> SketchState:
        """Step back one state (no-op at the start) and return the current state."""
        if self.can_undo:
            self._index -= 1
        return self.current

    def redo(self) -> SketchState:
        """Step forward one state (no-op at the end) and return the current state."""
        if self.can_redo:
            self._index += 1
        return self.current

    def reset(self, state: SketchState | None = None) -> None:
        """Forget all history; ``state`` (default: empty) becomes the only state."""
        self._states = [state if state is not None else SketchState()]
        self._index = 0
