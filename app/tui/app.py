"""The Textual TUI that guides the operator through a calibration session.

A second front end of the one session runner (the headless one is :mod:`acq.session.headless`): the runner thread
does all device I/O and storage; this app shows the plan, the current step's instructions and set-up diagram, the
live readings, the checks, per-step results and a plot, and answers the runner's prompts from the keyboard.
See :mod:`app.tui.bridge` for how the two threads meet.
"""
from __future__ import annotations

import asyncio
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from textual import on
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Header, Markdown, RichLog, Static, Tree
from textual_plotext import PlotextPlot

from app.interrupt import kept_text, report_text
from acq.session.runner import Answer, Event, Runner

from app.tui.bridge import LiveValues, OperatorPrompt, RunnerEvent, TuiOperator
from app.tui.fields import ConfirmAbort, ValueField, input_rows, parse_value
from app.tui.panels import Progress, check_row, joint_table, point_lines, shorten, table_of, theodolite_lines
from app.tui.views import DIAGRAMS, StepData, plot_series

HELP = """\
# robocal session — keys

| key | what it does |
|---|---|
| **c** | continue: the set-up of this step is done (type the measured values first) |
| **a** | accept the readings of this step (they are saved only then) |
| **r** | repeat the step |
| **s** | skip the step |
| **p** | pause: the session stops after this step and resumes where it stopped |
| **x** | abort the session, after asking (everything saved so far stays) |
| **1** | show or hide the plan (folded on small terminals) |
| **2** | show or hide the devices and the log (folded on small terminals) |
| **d** | show or hide the set-up diagram |
| **PgUp PgDn** | scroll the step's column (checks, readings, plot) on a short terminal |
| **?** | this help |
| **q** | quit (a step in progress is not saved; the session resumes later) |

Values (a load, a gauge, a tilt): type the number you measured in its field -- the plan's value is shown greyed as a
hint and is never entered for you. **Enter** takes the value, **Escape** puts the field back as it was; both hand
the keys back to the step, and the step's keys work even while a field has focus. **Tab** goes from field to field.

Checks: *face I / face II* — the two faces of a theodolite must agree; *spread* — repeat sightings must agree;
*miss distance* — the sight lines from A and B must nearly meet; *encoders settled* — the robot must be still;
*plausibility* — the point must be near where the robot model puts it.  A failed check: look at the message,
repeat the step, or accept it anyway if you know why.
"""


class HelpScreen(ModalScreen[None]):
    BINDINGS = [Binding("escape,question_mark,q", "dismiss", "close")]

    def compose(self) -> ComposeResult:
        yield VerticalScroll(Markdown(HELP), id="help")


@dataclass
class SessionHandle:
    """What a builder returns: the runner, how to close the devices, and a title."""

    runner: Runner
    close: Callable[[], None]
    title: str
    db_path: str = ""
    identities: list = None        # (role, driver, url, identity) read once by the builder, before the runner starts
    reduction: object = None       # app.live_reduction.SessionReduction: the results (None: reprocessed at the end)


Builder = Callable[[TuiOperator], SessionHandle]

CHECK_COLUMNS = ("check", "result", "value", "limit", "reason")
STATUS_MARK = {"done": "✔", "accepted": "✔", "warned": "⚠", "skipped": "↷", "current": "▶", "failed": "✗",
               "": "·"}


class RobocalApp(App):
    """``RobocalApp(builder)``: ``builder(operator)`` wires devices and the runner (emulated or real)."""

    TITLE = "robocal session"
    CSS = """
    #body { height: 1fr; }
    #plan { width: 36; border: round $primary; }
    #middle { width: 1fr; min-width: 40; }
    #right { width: 48; }
    #step { height: auto; min-height: 4; border: round $accent; padding: 0 1; }
    #diagram { height: auto; color: $text-muted; padding: 0 1; }
    #prompt { height: auto; padding: 0 1; background: $boost; }
    #keys { dock: bottom; height: 1; background: $panel; padding: 0 1; }
    #inputs { height: auto; padding: 0 1; }
    .input-row { height: 1; }
    .input-label { width: auto; padding: 0 1 0 0; }
    ValueField { width: 18; }
    #live { height: auto; border: round $success; padding: 0 1; display: none; }
    #live.has-data { display: block; }
    #checks { height: auto; border: round $primary; padding: 0 1; display: none; }
    #checks.has-rows { display: block; }
    #confirm { width: 64; max-width: 100%; height: auto; border: thick $error; background: $surface; padding: 1 2; }
    ConfirmAbort { align: center middle; }
    #plot { height: 1fr; min-height: 12; border: round $primary; display: none; }
    #plot.has-data { display: block; }
    #devices { height: auto; border: round $primary; padding: 0 1; }
    #log { height: 1fr; border: round $primary; }
    #help { width: 80; max-width: 100%; height: 80%; border: thick $accent; background: $surface; }
    HelpScreen { align: center middle; }
    /* small terminals: the step gets the room; side panels fold behind keys 1 (plan) and 2 (devices, log) */
    Screen.-medium #plan { width: 28; }
    Screen.-medium #right { display: none; }
    Screen.-narrow #plan { display: none; }
    Screen.-narrow #right { display: none; }
    Screen.-short #diagram { display: none; }
    /* short terminals (80x24): no frames -- their rows go to the checks; the panels keep a tint or a rule apart */
    Screen.-short #step { border: none; min-height: 2; background: $boost; }
    Screen.-short #live { border: none; border-top: hkey $success; }
    Screen.-short #checks { border: none; border-top: hkey $primary; }
    #body.show-plan #plan { display: block; }
    #body.show-side #right { display: block; }
    #body.show-diagram #diagram { display: block; }
    #body.hide-plan #plan { display: none; }
    #body.hide-side #right { display: none; }
    """
    #: widths (columns) and heights (rows) at which the layout changes; classes are set on the screen
    HORIZONTAL_BREAKPOINTS = [(0, "-narrow"), (110, "-medium"), (160, "-wide")]
    VERTICAL_BREAKPOINTS = [(0, "-short"), (36, "-tall")]
    ENABLE_COMMAND_PALETTE = False        # ^p in the footer cost the room of two keys at 80 columns
    BINDINGS = [
        Binding("c", "answer('continue')", "continue"),
        Binding("a", "answer('accept')", "accept"),
        Binding("r", "answer('repeat')", "repeat"),
        Binding("s", "answer('skip')", "skip"),
        Binding("p", "answer('pause')", "pause"),
        Binding("x", "answer('abort')", "abort"),
        Binding("1", "toggle_panel('plan')", "plan"),
        Binding("2", "toggle_panel('side')", "log"),
        Binding("d", "toggle_panel('diagram')", "diagram", show=False),
        Binding("question_mark", "help", "help"),
        Binding("q", "quit", "quit"),
        Binding("ctrl+c", "interrupt", "quit", show=False, priority=True),  # what an operator presses to get out
        Binding("tab", "next_field", "next field", show=False, priority=True),
        Binding("pagedown", "scroll_step(1)", "scroll", show=False),
        Binding("pageup", "scroll_step(-1)", "scroll", show=False),
    ]

    def __init__(self, builder: Builder, live_hz: float = 10.0, clock: bool = True, final_results: bool = True,
                 resume_command: str | None = None):
        super().__init__()
        #: the exact command that resumes this session (``robocal session`` passes its own), shown when it stops
        self.resume_command = resume_command
        self.ended_by: str | None = None                     # "interrupt" (Ctrl-C) or "hangup" (terminal closed)
        self.db_path = ""
        self.clock = clock
        self.final_results = final_results
        self.results_dir: str | None = None
        self.plotted: tuple[str, int] | None = None       # what the plot shows now: (title, points)
        self.builder = builder
        self.live_hz = live_hz
        self.operator = TuiOperator()
        self.live = LiveValues()
        self.handle: SessionHandle | None = None
        self.pending: OperatorPrompt | None = None
        self.steps_by_key: dict = {}
        self.nodes: dict = {}
        self.data: dict[str, StepData] = {}
        self.current_key: str | None = None
        self.finished: dict | None = None
        self.state = "idle"
        self.results: list[str] = []
        self.progress = Progress()
        self.groups: dict = {}                               # procedure -> its node in the plan tree
        self.step_t0: dict[str, float] = {}                  # key -> when the step started (for the estimate)
        self.preflight_lines: list[str] = []                 # why the runner refused to start, one line a step
        self.table_columns: list[str] = list(CHECK_COLUMNS)  # what the checks panel shows now (tests read it)
        self.table_rows: list[tuple] = []
        self._panels: dict[str, Static] = {}

    # -- layout -------------------------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Header(show_clock=self.clock)
        with Horizontal(id="body"):
            yield Tree("plan", id="plan")
            with VerticalScroll(id="middle"):
                yield Static("starting…", id="step")
                yield Static("", id="diagram")
                yield Static("", id="prompt")
                yield Vertical(id="inputs")
                yield Static("no readings yet", id="live")
                yield Static("", id="checks")
                yield PlotextPlot(id="plot")
            with Vertical(id="right"):
                yield Static("", id="devices")
                yield RichLog(id="log", wrap=True, markup=False, min_width=20)   # wrapped to its column
        yield Static("", id="keys")

    def panel(self, selector: str) -> Static:
        """A panel of the main screen, found once: timers and resizes reach it while a modal (help, the abort
        question) is on top, where a query of the active screen finds nothing."""
        return self._panels[selector]

    def on_mount(self) -> None:
        # only the value fields take focus: Tab goes to the first field whatever the width (the plan tree, shown
        # only on wide screens, used to come first), and the step's keys are never caught by a panel
        self.query_one("#plan", Tree).can_focus = False
        self.query_one("#middle").can_focus = False
        self.query_one("#log").can_focus = False
        self._panels = {sel: self.query_one(sel) for sel in ("#middle", "#checks", "#live", "#devices", "#keys")}
        self._refresh_keys()
        self.operator.app = self
        try:                                   # a closed terminal ends the session as Ctrl-C does (main thread only)
            asyncio.get_running_loop().add_signal_handler(signal.SIGHUP, self._hung_up)
        except (AttributeError, NotImplementedError, RuntimeError, ValueError):
            pass
        self.query_one("#step", Static).update("Connecting to the instruments…")
        # opening devices does I/O: never in the UI thread
        threading.Thread(target=self._connect, name="robocal-connect", daemon=True).start()

    def _connect(self) -> None:
        try:
            handle = self.builder(self.operator)
        except Exception as exc:                          # noqa: BLE001 - shown to the operator
            self.call_from_thread(self._cannot_start, exc)
            return
        self.call_from_thread(self._session_ready, handle)

    def _cannot_start(self, exc: Exception) -> None:
        self.log_line(f"cannot start the session: {exc}")
        self.query_one("#step", Static).update(
            f"[b red]Cannot start the session[/]\n{exc}\n\nCheck that the instruments are connected and powered, "
            f"and the URLs/ports. Press q to quit.")
        self.finished = {"exit_status": "failed", "error": str(exc)}

    def _session_ready(self, handle: "SessionHandle") -> None:
        if self.operator.closed.is_set():                   # the app was closed while connecting
            handle.close()
            return
        self.handle = handle
        self.db_path = handle.db_path                       # kept after the handle is closed, for the last words
        runner = handle.runner
        self.sub_title = handle.title
        self._build_plan(runner)
        runner.subscribe(self._from_runner)                # called in the runner thread
        runner.start()
        self.timers = [self.set_interval(1.0 / self.live_hz, self._refresh_live),
                       self.set_interval(1.0, self._refresh_devices)]
        self._refresh_devices()

    #: width of the step's column from which the checks and results are a table of columns; narrower, each row is
    #: its first column then the rest as one wrapped text (a reason column of 12 characters was unreadable)
    WIDE_TABLE_COLUMNS = 110

    #: header columns that are not the title: the icon, the clock, the " — " and the margins
    HEADER_RESERVED = 22

    #: characters of a step title shown in the plan tree (the full title shows when the node is highlighted)
    PLAN_LABEL_CHARS = 28

    def _build_plan(self, runner: Runner) -> None:
        tree = self.query_one("#plan", Tree)
        tree.show_root = False
        tree.guide_depth = 2
        tree.root.expand()
        self.progress = Progress.of([s.procedure for s in runner.steps])
        for step in runner.steps:
            self.steps_by_key[step.key] = step
            if step.procedure not in self.groups:
                self.groups[step.procedure] = tree.root.add(self.progress.group_label(step.procedure), expand=False)
            self.nodes[step.key] = self.groups[step.procedure].add_leaf(
                f"· {shorten(step.title, self.PLAN_LABEL_CHARS)}", data=step.key)
        self._show_progress()

    def _show_progress(self) -> None:
        for proc, node in self.groups.items():
            node.set_label(self.progress.group_label(proc))
        cur = self.steps_by_key[self.current_key].procedure if self.current_key in self.steps_by_key else None
        room = self.size.width - self.HEADER_RESERVED - len(self.TITLE)
        self.title = self.TITLE if room >= 40 else "robocal"          # 80 columns: the progress needs the room
        self.sub_title = self.progress.header(cur, time.monotonic(), self.size.width - self.HEADER_RESERVED
                                              - len(self.title))

    def _relayout_text(self) -> None:
        """Measure the wrapped texts again at the width they have now: a text set while the layout was still
        settling (start-up, a breakpoint change, a resize) must never keep the height of a wider column."""
        for w in self.query("#step, #prompt, #live, #diagram"):
            w.refresh(layout=True)

    def on_resize(self, event) -> None:
        self.call_after_refresh(self._relayout_text)
        self.call_after_refresh(lambda: self._show_table(self.table_columns, self.table_rows))

    @on(Tree.NodeHighlighted, "#plan")
    def _plan_highlighted(self, event: Tree.NodeHighlighted) -> None:
        step = self.steps_by_key.get(event.node.data) if event.node.data else None
        self.query_one("#plan", Tree).border_subtitle = step.title if step is not None else ""

    def action_toggle_panel(self, which: str) -> None:
        """Show or hide a side panel (the plan, the devices and log, the set-up diagram) at any terminal size."""
        body = self.query_one("#body")
        target = {"plan": "#plan", "side": "#right", "diagram": "#diagram"}[which]
        shown = self.query_one(target).display
        body.remove_class(f"show-{which}", f"hide-{which}")
        body.add_class(f"hide-{which}" if shown else f"show-{which}")

    # -- runner thread -> app -------------------------------------------------------------------------------------
    def _from_runner(self, ev: Event) -> None:
        if ev.kind == "reading":
            self.live.put(f"theodolite {ev.data.get('station')}", ev.data)
        elif ev.kind == "encoders":
            self.live.put("encoders", ev.data)
        self.post_message(RunnerEvent(ev))

    @on(RunnerEvent)
    def _on_event(self, message: RunnerEvent) -> None:
        ev = message.event
        d = ev.data
        handler = getattr(self, f"_ev_{ev.kind}", None)
        if handler is not None:
            handler(d)

    def _ev_state(self, d: dict) -> None:
        self.state = d.get("new", "")                # shown in the devices panel; the log is for what the operator acts on
        self._refresh_devices()                  # the state line follows the event, not the next timer tick

    def _ev_session(self, d: dict) -> None:
        resumed = " (resumed)" if d.get("resumed") else ""
        self.log_line(f"session {d.get('guid', '')[:8]}{resumed}: {d.get('done')} of {d.get('total')} steps saved"
                      f" — {d.get('path')}")

    def _ev_step_skipped_done(self, d: dict) -> None:
        self._mark(d["key"], "done")
        step = self.steps_by_key.get(d["key"])
        if step is not None:
            self.progress.mark_done(step.procedure)
            self._show_progress()

    def _ev_step_started(self, d: dict) -> None:
        key = d["key"]
        if self.current_key and self.current_key != key and self._status(self.current_key) == "current":
            self._mark(self.current_key, "")
        self.current_key = key
        self.step_t0.setdefault(key, time.monotonic())
        step = self.steps_by_key.get(key)
        self.data[key] = StepData(key, d.get("procedure", ""), dict(step.meta) if step else {})
        self._mark(key, "current")
        node = self.nodes.get(key)
        if node is not None:
            node.parent.expand()
            self.query_one("#plan", Tree).move_cursor(node)
        pose = d.get("pose_deg")
        pose_txt = ("\nrobot pose (deg): " + "  ".join(f"{v:.1f}" for v in pose)) if pose else ""
        attempt = f"  (attempt {d.get('attempt')})" if d.get("attempt", 1) > 1 else ""
        self.query_one("#step", Static).update(
            f"[b]{d.get('title', key)}[/b]{attempt}   step {d.get('index', 0) + 1} of {d.get('total', '?')}\n"
            f"{d.get('instruction', '')}{pose_txt}")
        self.query_one("#diagram", Static).update(DIAGRAMS.get(d.get("procedure", ""), ""))
        self.call_after_refresh(self._relayout_text)
        self._show_table(CHECK_COLUMNS, [])
        self._show_progress()

    def _ev_reading(self, d: dict) -> None:
        sd = self.data.get(d.get("key"))
        if sd is not None:
            sd.readings.append((d.get("station"), d.get("target"), d.get("face"), np.radians(d["hz_deg"]),
                                np.radians(d["v_deg"])))

    def _ev_encoders(self, d: dict) -> None:
        sd = self.data.get(d.get("key"))
        if sd is not None and d.get("joint_deg") is not None:
            sd.joint_deg = list(d["joint_deg"])

    def _ev_check(self, d: dict) -> None:
        sd = self.data.get(d.get("key"))
        if sd is not None:
            sd.checks.append(d)
        row = check_row(d)
        failed = [r for r in self.table_rows if "FAIL" in r[1]]            # failures first: seen without scrolling
        passed = [r for r in self.table_rows if "FAIL" not in r[1]]
        self._show_table(CHECK_COLUMNS, failed + [row] + passed if "FAIL" in row[1] else failed + passed + [row])
        if not d.get("passed", True):
            self.log_line(f"{d.get('key', '')}: {d.get('name', '')} FAILED — {d.get('message', '')}")

    def _show_table(self, columns, rows: list[tuple]) -> None:
        """The checks panel (later the results): a table as wide as the panel, reasons wrapped, every row shown."""
        self.table_columns, self.table_rows = list(columns), list(rows)
        panel = self.panel("#checks")
        panel.set_class(bool(rows), "has-rows")
        wide = self.panel("#middle").size.width >= self.WIDE_TABLE_COLUMNS
        panel.update(table_of(self.table_columns, self.table_rows, stacked=not wide) if rows else "")

    def _ev_step_saved(self, d: dict) -> None:
        key = d["key"]
        status = d.get("status", "accepted")
        sd = self.data.get(key)
        failed = sd is not None and any(not c.get("passed", True) for c in sd.checks)
        self._mark(key, "skipped" if status == "skipped" else ("warned" if failed else "accepted"))
        step = self.steps_by_key.get(key)
        if step is not None:
            t0 = self.step_t0.pop(key, None)
            now = time.monotonic()
            self.progress.mark_done(step.procedure, None if t0 is None else now - t0, now_s=now)
            self._show_progress()
        if sd is not None:
            sd.status = status
            self._update_plot(sd.procedure)

    def _ev_log(self, d: dict) -> None:
        self.log_line(d.get("text", ""))

    def _ev_preflight(self, d: dict) -> None:
        self.preflight_lines = list(d.get("lines", []))

    def _ev_finished(self, d: dict) -> None:
        self.finished = d
        err = d.get("error")
        status = d.get("exit_status")
        where = self.handle.db_path if self.handle else ""
        if status == "refused":
            lines = "\n".join(f"  {ln}" for ln in self.preflight_lines) or f"  {err}"
            msg = (f"[b red]The session did not start: {err}[/]\n{lines}\nNothing was recorded. Change the plan or "
                   f"the set-up so these steps pass (robocal plan check prints the pre-flight; the operator guide "
                   f"says what each check means), then start again.")
        elif err:
            msg = (f"[b red]The session stopped: {err}[/]\n{self.kept()}\nFix the cause (device connected? "
                   f"powered?) first.")
        elif status in ("paused", "abort"):
            msg = f"[b]{'Paused' if status == 'paused' else 'Aborted'}.[/] {self.kept()}"
        else:
            msg = f"[b green]Session {status}.[/] Data: {where}\n{report_text(where)}"
            if status == "success" and where and self.final_results:
                msg += "\nComputing the results…"
                reduction = self.handle.reduction if self.handle else None
                threading.Thread(target=self._final_results, args=(where, reduction), daemon=True).start()
        self.query_one("#step", Static).update(msg + "\n\nPress q to quit.")
        self.query_one("#prompt", Static).update("")
        self._refresh_keys()

    def kept(self) -> str:
        """How many steps are saved, where, and the exact command that resumes (every way a session stops)."""
        where = self.db_path or "the session database"
        resume = self.resume_command or "the same robocal session command, same --db"
        return kept_text(self.progress.steps_done, self.progress.steps_total, where, resume)

    def _final_results(self, db: str, reduction=None) -> None:
        """The finished session's results -- from the reduction that ran beside it, else reprocessed (read-only) --
        and its report, off the UI thread."""
        try:
            from offline.report import write_report
            from app.reprocess import reprocess

            res = reduction.results() if reduction is not None else reprocess(db)
            out = str(Path(db).with_suffix("")) + "_report"
            write_report(res, out)
        except Exception as exc:                            # noqa: BLE001 - results are a convenience here
            self.call_from_thread(self.log_line, f"results not computed: {exc}")
            return
        self.call_from_thread(self._show_results, res, out)

    def _show_results(self, res: dict, out: str) -> None:
        from offline.summary import estimate_rows          # names, units and rounding as the summary has them
        self._show_table(("estimate", "value ± 1σ", "unit", "truth", "verdict"),
                         [row[:5] for row in estimate_rows(res)])
        self.results_dir = out
        where = self.handle.db_path if self.handle else ""
        self.query_one("#step", Static).update(
            f"[b green]Session success.[/] Data: {where}\nReport: {out}/report.html  "
            f"({len(res.get('estimates', []))} estimates with their errors below)\n\nPress q to quit.")
        self.log_line(f"report written to {out}")

    # -- prompts ------------------------------------------------------------------------------------------------------
    KEYS = {"continue": "c", "accept": "a", "repeat": "r", "skip": "s", "pause": "p", "abort": "x"}

    @on(OperatorPrompt)
    def _on_prompt(self, message: OperatorPrompt) -> None:
        self.pending = message
        req = message.request
        choices = "   ".join(f"[b]{self.KEYS[c]}[/] {c}" for c in req.choices if c in self.KEYS)
        if req.kind == "decision":
            failed = [c for c in req.checks if not getattr(c, "passed", True)]
            head = (f"[b red]{len(failed)} check(s) failed[/] — repeat, or accept if you know why"
                    if failed else "[green]all checks passed[/]")
            if "accept" not in req.choices and failed:
                head = f"[b red]{len(failed)} check(s) failed[/] — nothing was recorded: fix it and repeat"
        elif req.step.inputs:
            head = "Do what the step says, type each value you measured (Enter), then continue"
        else:
            head = "Do what the step says, then continue"
        self.query_one("#prompt", Static).update(f"{head}\n{choices}")
        self.call_after_refresh(self._relayout_text)
        box = self.query_one("#inputs", Vertical)
        box.remove_children()
        if req.kind == "setup" and req.step.inputs:
            box.mount_all(input_rows(req.step.inputs))
            self.call_after_refresh(self._focus_field, req.step.inputs[0].name)
        self._refresh_keys()

    def _focus_field(self, name: str) -> None:
        fields = self.query(f"#in-{name}")
        if fields:
            fields.first().focus()

    @on(ValueField.Done)
    def _field_done(self, message: ValueField.Done) -> None:
        """Enter or Escape in a field: the keys go back to the step (a value that is not a number stays to fix)."""
        text = message.field.value.strip()
        if message.accepted and text and parse_value(text) is None:
            spec = message.field.spec
            self.notify(f"{spec.prompt}: '{text}' is not a number ({spec.unit})", severity="error")
            return
        self.set_focus(None)

    def action_scroll_step(self, direction: int) -> None:
        """Page Up / Down: the step's column (checks, readings, plot) on a terminal too short for all of it."""
        middle = self.query_one("#middle")
        (middle.scroll_page_down if direction > 0 else middle.scroll_page_up)()

    def action_next_field(self) -> None:
        """Tab: from the step's keys to the first field still empty (then field after field, in the step's order,
        whatever the width of the terminal)."""
        if self.focused is None:
            empty = [f for f in self.query(ValueField) if not f.value.strip()]
            fields = empty or list(self.query(ValueField))
            if fields:
                fields[0].focus()
            return
        self.screen.focus_next()

    def _refresh_keys(self) -> None:
        """The key bar: every key that acts now, with what it does, in one line (80 columns hold them all).

        Why not Textual's footer: it rebuilds its widgets whenever the keys change -- twice a prompt -- and that took
        a few hundred ms a key on a loaded 2-core machine (benchmarks/bench_tui_keys.py); this is one line of text."""
        shown = []
        for key, active in self.screen.active_bindings.items():
            b = active.binding
            if b.show and active.enabled and (b.action, key) not in shown:
                shown.append((b.action, key))
        text = "  ".join(f"[b]{self.get_key_display(self.screen.active_bindings[k].binding)}[/b] "
                         f"{self.screen.active_bindings[k].binding.description}" for _, k in shown)
        if text != getattr(self, "_keys_text", None):
            self._keys_text = text
            self.panel("#keys").update(text)

    def on_key(self, event) -> None:
        """A number typed while no field has focus (the operator types the moment the step appears, before the
        first field has taken focus) starts the first empty field: it is never lost, and never taken as a key."""
        if self.focused is None and event.character and event.character in "0123456789.-+":
            empty = [f for f in self.query(ValueField) if not f.value.strip()]
            if empty:
                field = empty[0]
                field.focus()
                field.value = event.character        # the field is empty, and takes no selection on focus
                field.cursor_position = len(field.value)
                event.stop()
                event.prevent_default()

    def on_descendant_focus(self, event) -> None:
        self._refresh_keys()                       # a field's number keys are its own while it has focus

    def on_descendant_blur(self, event) -> None:
        self.call_after_refresh(self._refresh_keys)

    def check_action(self, action: str, parameters: tuple) -> bool | None:
        """The footer shows the step's keys that do something now (the keys of a field never hide them)."""
        if action != "answer":
            return True
        choice = parameters[0] if parameters else ""
        msg = self.pending
        if msg is None or msg.future.done():
            # between prompts (acquiring): pause and abort still act, at the next step boundary
            return choice in ("pause", "abort") and self.handle is not None and self.finished is None
        return choice in msg.request.choices

    def action_answer(self, action: str) -> None:
        msg = self.pending
        if msg is None or msg.future.done():
            self._request_between_prompts(action)
            return
        if action not in msg.request.choices:
            self.notify(f"'{action}' is not possible now (choose: {', '.join(msg.request.choices)})", severity="warning")
            return
        if action == "abort":
            self.push_screen(ConfirmAbort(self.db_path or "the session database"), lambda yes: self._answer(msg, "abort", {}) if yes else None)
            return
        values = {}
        if action == "continue":
            values = self._entered_values(msg.request.step)
            if values is None:
                return
        self._answer(msg, action, values)

    def _entered_values(self, step) -> dict | None:
        """Every measured value of the step, typed by the operator; None (and the field named, focused) if one is
        missing or not a number: the plan's value is a hint, never a stand-in."""
        values = {}
        for spec in step.inputs:
            field = self.query_one(f"#in-{spec.name}", ValueField)
            text = field.value.strip()
            v = parse_value(text)
            if v is None:
                what = "not entered" if not text else f"'{text}' is not a number"
                plan = "" if spec.suggested is None else f" (the plan's {spec.suggested:g} is only a hint)"
                self.notify(f"{spec.prompt} ({spec.unit}): {what} — type the value you measured{plan}",
                            severity="error")
                field.focus()
                return None
            values[spec.name] = v
        sd = self.data.get(step.key)
        if sd is not None:
            sd.inputs.update(values)
        return values

    def _answer(self, msg: OperatorPrompt, action: str, values: dict) -> None:
        if msg.future.done():
            return
        self.pending = None
        self.query_one("#prompt", Static).update(f"[dim]{action}…[/]")
        self.query_one("#inputs", Vertical).remove_children()
        msg.future.set_result(Answer(action, values))
        self._refresh_keys()

    def _request_between_prompts(self, action: str) -> None:
        """``p`` / ``x`` while the runner acquires: it stops at the next step boundary (``x`` asks first)."""
        h = self.handle
        if h is None or self.finished is not None or action not in ("pause", "abort"):
            self.bell()
            return
        if action == "pause":
            h.runner.request_pause()
            self.notify("pausing after this step")
        else:
            self.push_screen(ConfirmAbort(self.db_path or "the session database"), lambda yes: h.runner.request_abort() if yes else None)

    def action_help(self) -> None:
        self.push_screen(HelpScreen())

    async def action_quit(self) -> None:
        self._stop_session()
        self.exit()

    async def action_interrupt(self) -> None:
        """Ctrl-C: quit as ``q`` does (committed steps are safe); ``robocal session`` then says what was kept."""
        self.ended_by = self.ended_by or "interrupt"
        await self.action_quit()

    def _hung_up(self) -> None:
        """SIGHUP (the terminal closed): stop between steps instead of dying in one, then say what was kept."""
        self.ended_by = "hangup"
        self._stop_session()
        self.exit()

    def _stop_session(self) -> None:
        for t in getattr(self, "timers", []):           # no panel refresh while the screen is taken down
            t.stop()
        self.operator.closed.set()
        if self.pending is not None and not self.pending.future.done():
            self.pending.future.set_result(Answer("abort"))
        h = self.handle
        if h is not None:
            h.runner.request_abort()
            h.runner.join(5.0)
            try:
                h.close()
            except Exception:                              # noqa: BLE001 - closing on exit is best effort
                pass
            self.handle = None

    def on_unmount(self) -> None:
        self._stop_session()

    # -- views ---------------------------------------------------------------------------------------------------
    def _status(self, key: str) -> str:
        node = self.nodes.get(key)
        return getattr(node, "_robocal_status", "") if node is not None else ""

    def _mark(self, key: str, status: str) -> None:
        node = self.nodes.get(key)
        if node is None:
            return
        node._robocal_status = status
        step = self.steps_by_key[key]
        node.set_label(f"{STATUS_MARK.get(status, '·')} {shorten(step.title, self.PLAN_LABEL_CHARS)}")

    def log_line(self, text: str) -> None:
        stamp = f"{time.strftime('%H:%M:%S')} " if self.clock else ""
        self.query_one("#log", RichLog).write(f"{stamp}{text}")

    def _refresh_live(self) -> None:
        """Latest readings, labelled: one line per theodolite, the intersected points, the encoders per joint."""
        snap = self.live.snapshot()
        theo = {k.split(" ", 1)[1]: v for k, v in snap.items() if k.startswith("theodolite ") and v}
        lines = theodolite_lines(theo)
        sd = self.data.get(self.current_key) if self.current_key else None
        if sd is not None and self.handle is not None:
            lines += point_lines(sd.points(self.handle.runner.stations))
            miss = [c for c in sd.checks if c.get("name", "").startswith("miss")]
            if miss and miss[-1].get("value") is not None:
                lines.append(f"miss distance {miss[-1]['value']:.3f} mm")
        tap = getattr(self.handle.runner.rig, "tap", None) if self.handle else None
        sample = tap.latest() if tap is not None else None
        if sample is not None:
            live = self.panel("#live")
            width = max(live.size.width or 76, 20)             # the content's width (frame and padding excluded)
            lines += joint_table(sample.counts, sample.joint_rad, width)
        live = self.panel("#live")
        live.set_class(bool(lines), "has-data")
        live.update("\n".join(lines) or "no readings yet")

    def _refresh_devices(self) -> None:
        if self.handle is None:
            return
        if self.finished is None and self.steps_by_key:
            self._show_progress()                          # the time left counts down between steps
        rig = self.handle.runner.rig
        lines = []
        # identities were read by the builder; the UI thread never talks to a device (the runner thread owns them)
        for role, driver, url, ident in self.handle.identities or []:
            who = ident.get("serial") or ident.get("name") or ""
            lines.append(f"{role}: {driver} {who} {url}".rstrip())
        tap = getattr(rig, "tap", None)
        if tap is not None:
            s = tap.stats
            health = "[green]ok[/]" if not s.last_error else f"[red]{s.last_error}[/] — check the cable / bus"
            lines.append(f"tap: {s.frames} frames, {s.bad_frames} bad, {getattr(s, 'lost_samples', 0)} lost, "
                         f"{s.reconnects} reconnects — {health}")
        lines.append(f"state: {self.state}")
        self.panel("#devices").update("\n".join(lines))

    def _update_plot(self, procedure: str) -> None:
        if self.handle is None:
            return
        steps = [s for s in self.data.values() if s.procedure == procedure and s.status not in ("skipped", "")]
        same_joint = [s for s in steps if s.meta.get("joint") == self.data[self.current_key].meta.get("joint")] \
            if self.current_key in self.data else steps
        try:
            series = plot_series(procedure, same_joint or steps, self.handle.runner.stations)
        except Exception as exc:                            # noqa: BLE001 - a plot never stops the session
            self.log_line(f"plot: {exc}")
            return
        if series is None:
            return
        title, xlabel, ylabel, lines = series
        self.plotted = (title, sum(len(xs) for _, xs, _ in lines))
        plot = self.query_one("#plot", PlotextPlot)
        plot.add_class("has-data")
        plt = plot.plt
        plt.clear_data()
        plt.clear_figure()
        for label, xs, ys in lines:
            plt.plot(xs, ys, label=label, marker="dot")
        plt.title(title)
        plt.xlabel(xlabel)
        plt.ylabel(ylabel)
        plot.refresh()
