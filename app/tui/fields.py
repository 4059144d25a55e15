"""The value fields of a set-up prompt and the abort confirmation: entry that never traps the operator.

Why a field of its own: a plain text input swallows every printable key, so once it had focus the step's keys (``c``
continue, ``x`` abort ...) were typed into it (``25c``), Enter and Escape did nothing and the footer lost its hints.
A :class:`ValueField` takes only what a number is written with; every other key goes on to the step's bindings (and
the footer keeps showing them), Enter accepts the value and hands the keys back to the step, Escape puts back the
value the field had and hands them back too.  The plan's value is the placeholder, never the content: a measured
value is typed by the operator or it is missing.
"""
from __future__ import annotations

from textual import events
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.message import Message
from textual.screen import ModalScreen
from textual.widgets import Input, Static

from acq.session.steps import InputSpec

#: the characters a number is written with (digits, sign, decimal point, exponent); other keys stay the step's
NUMBER_CHARS = frozenset("0123456789+-.eE")


def parse_value(text: str) -> float | None:
    """The number typed, or None when the text is not a finite number (empty included)."""
    try:
        v = float(text.strip())
    except ValueError:
        return None
    return v if v == v and abs(v) != float("inf") else None


def hint(spec: InputSpec) -> str:
    """The placeholder of a field: the unit and what the plan asks for (never filled in)."""
    return spec.unit if spec.suggested is None else f"plan {spec.suggested:g} {spec.unit}"


class ValueField(Input):
    """A number field: numeric keys are typed, every other key is the step's; Enter accepts, Escape restores."""

    BINDINGS = [Binding("escape", "restore", "leave unchanged", show=False)]

    class Done(Message):
        """The operator left the field (Enter: ``accepted``; Escape: restored)."""

        def __init__(self, field: "ValueField", accepted: bool) -> None:
            super().__init__()
            self.field = field
            self.accepted = accepted

    def __init__(self, spec: InputSpec, **kwargs) -> None:
        # no select-all on focus: a digit that arrived before the focus (App.on_key) is kept, not replaced
        super().__init__(value="", placeholder=hint(spec), type="number", id=f"in-{spec.name}", compact=True,
                         select_on_focus=False, **kwargs)
        self.spec = spec
        self._before = ""

    def check_consume_key(self, key: str, character: str | None) -> bool:
        """Only number characters are the field's: the footer keeps showing the step's keys while it has focus."""
        return character is not None and character in NUMBER_CHARS

    async def _on_key(self, event: events.Key) -> None:
        if event.is_printable and event.character not in NUMBER_CHARS:
            event.prevent_default()          # not typed here: the key bubbles on to the step's bindings

    async def action_submit(self) -> None:
        """Enter: the value is taken (checked by the app) and the keys go back to the step."""
        self.post_message(self.Done(self, True))

    def _on_focus(self, event: events.Focus) -> None:
        self._before = self.value

    def action_restore(self) -> None:
        self.value = self._before
        self.post_message(self.Done(self, False))


class InputRow(Horizontal):
    """One measured value: its prompt and unit, then the field, on one line (three fit at 80x24)."""

    def __init__(self, spec: InputSpec, label_width: int) -> None:
        super().__init__(classes="input-row")
        self.spec = spec
        self.label_width = label_width

    def compose(self) -> ComposeResult:
        label = Static(label_text(self.spec), classes="input-label")
        label.styles.width = self.label_width          # the fields of one step stand in one column
        yield label
        yield ValueField(self.spec)


def label_text(spec: InputSpec) -> str:
    return f"{spec.prompt} ({spec.unit})"


def input_rows(specs) -> list[InputRow]:
    """The rows of a set-up prompt, their labels as wide as the widest."""
    width = max((len(label_text(s)) for s in specs), default=0) + 1
    return [InputRow(s, width) for s in specs]


class ConfirmAbort(ModalScreen[bool]):
    """``x`` asks first: an abort ends the session (what was saved stays; the step in hand is not saved)."""

    BINDINGS = [Binding("y", "answer(True)", "abort"), Binding("n,escape", "answer(False)", "go back")]

    def __init__(self, where: str) -> None:
        super().__init__()
        self.where = where

    def compose(self) -> ComposeResult:
        with Vertical(id="confirm"):
            yield Static(f"[b]Abort the session?[/b]\nThe steps saved so far stay in {self.where}; the step in hand "
                         f"is not saved. Start the session again with the same --db to resume.\n\n"
                         f"[b]y[/b] abort    [b]n[/b] / [b]Escape[/b] go back")

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)
