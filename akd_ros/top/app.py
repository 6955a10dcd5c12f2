"""akd-top's view (Textual): a table of one row per joint, the bus's line below it, a row per device beside the drives
with its channels (a device out of reach highlighted; the table shown only where there are devices), the line's slaves
with each port's link and error counters (a port whose counters rose in the last seconds highlighted, the worst place
on the line said above them), the outcome of the last request, and the keys that ask the selected joint for
something, each after a confirmation. Written once over `akd_ros.top.source.Source`."""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual import work
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Grid
from textual.screen import ModalScreen
from textual.widgets import Button, DataTable, Footer, Header, Label, Static

from akd_ros.top.source import DeviceRow, LineView, Source

COLUMNS = (
    ("joint", "joint"),
    ("state", "DS402 state"),
    ("mode", "mode"),
    ("position", "position"),
    ("velocity", "velocity"),
    ("torque", "torque"),
    ("following_error", "following error"),
    ("fault", "last fault"),
    ("io", "I/O"),
)
DEVICE_COLUMNS = (
    ("device", "device"),
    ("slave", "slave"),
    ("product", "product"),
    ("inputs", "inputs"),
    ("outputs", "outputs"),
    ("message", "status"),
)
"""The devices table's columns: each direction's channels of one bit as 0/1 digits (the first channel first), its
other channels as name=value."""
LINE_COLUMNS = (
    ("slave", "slave"),
    ("port", "port"),
    ("link", "link"),
    ("peer", "other end"),
    ("invalid_frames", "invalid frames"),
    ("rx_errors", "RX errors"),
    ("forwarded_errors", "forwarded"),
    ("lost_links", "lost links"),
    ("window", "lately"),
)
"""The line table's columns: one row per port of each slave, its counters since the start, then what they counted
over the last seconds."""
LEVEL_STYLES = {0: "", 1: "bold yellow", 2: "bold red"}
"""How a row of the line is shown by its status's level: a port whose counters rose, or a slave out of reach."""
REFRESH_S = 0.1
"""How often the view reads its source."""
ACTION_WORDS = {
    "enable": "enable",
    "disable": "disable",
    "quick_stop": "quick-stop",
    "reset_fault": "reset the fault of",
}
LATCHES = {"1": (1, "rising"), "2": (1, "falling"), "3": (2, "rising"), "4": (2, "falling")}
"""The latch screen's keys: channel and edge."""


def cell(value) -> str:
    """A value as its cell shows it: numbers to 6 significant digits, '-' for none."""
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


class Confirm(ModalScreen[bool]):
    """Asks yes or no (keys y and n, or the buttons); dismisses with the answer."""

    BINDINGS: ClassVar = [Binding("y", "answer(True)", "yes"), Binding("n,escape", "answer(False)", "no")]
    DEFAULT_CSS = """
    Confirm { align: center middle; }
    #dialog { grid-size: 2; grid-gutter: 1 2; padding: 1 2; width: 64; height: 11; border: thick $warning; }
    #question { column-span: 2; height: 3; width: 1fr; content-align: center middle; }
    Button { width: 100%; }
    """

    def __init__(self, question: str) -> None:
        super().__init__()
        self.question = question

    def compose(self) -> ComposeResult:
        with Grid(id="dialog"):
            yield Label(self.question, id="question")
            yield Button("Yes (y)", variant="warning", id="yes")
            yield Button("No (n)", variant="primary", id="no")

    def on_button_pressed(self, event: Button.Pressed) -> None:
        self.dismiss(event.button.id == "yes")

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)


class ChooseLatch(ModalScreen[tuple[int, str] | None]):
    """Asks which latch to arm on which edge (keys 1-4); dismisses with (channel, edge), None on escape."""

    BINDINGS: ClassVar = [Binding(key, f"choose('{key}')", f"latch {c} {e}") for key, (c, e) in LATCHES.items()] + [
        Binding("escape,n", "choose('')", "cancel")
    ]
    DEFAULT_CSS = """
    ChooseLatch { align: center middle; }
    #latches { padding: 1 2; width: 64; height: 10; border: thick $accent; }
    """

    def __init__(self, joint: str) -> None:
        super().__init__()
        self.joint = joint

    def compose(self) -> ComposeResult:
        choices = "\n".join(f"  {key}: latch {c}, {e} edge" for key, (c, e) in LATCHES.items())
        yield Static(f"Arm which latch of {self.joint}?\n{choices}\n  escape: cancel", id="latches")

    def action_choose(self, key: str) -> None:
        self.dismiss(LATCHES.get(key))


class Top(App):
    """The live view of `source`."""

    TITLE = "akd-top"
    BINDINGS: ClassVar = [
        Binding("e", "ask('enable')", "enable"),
        Binding("d", "ask('disable')", "disable"),
        Binding("s", "ask('quick_stop')", "quick stop"),
        Binding("r", "ask('reset_fault')", "reset fault"),
        Binding("l", "latch", "arm latch"),
        Binding("q", "quit", "quit"),
    ]

    def __init__(self, source: Source, *, refresh_s: float = REFRESH_S) -> None:
        super().__init__()
        self.source = source
        self.refresh_s = refresh_s
        self.last_outcome = ""
        """What the last request came to, as the status line shows it."""
        self.bus_text = ""
        """The bus's lines as shown."""
        self.line_text = ""
        """The line's summary as shown."""

    def compose(self) -> ComposeResult:
        # Kept, not queried: a query looks in the screen on top, which is a confirmation while one is open.
        self.table = DataTable(id="joints", cursor_type="row", zebra_stripes=True)
        self.bus_line = Static(id="bus")
        self.device_table = DataTable(id="devices", cursor_type="none", zebra_stripes=True)
        self.device_table.display = False
        self.line_summary = Static(id="line")
        self.line_table = DataTable(id="ports", cursor_type="none", zebra_stripes=True)
        self.outcome_line = Static(id="outcome")
        yield Header()
        yield self.table
        yield self.bus_line
        yield self.device_table
        yield self.line_summary
        yield self.line_table
        yield self.outcome_line
        yield Footer()

    def on_mount(self) -> None:
        for key, label in COLUMNS:
            self.table.add_column(label, key=key)
        for key, label in DEVICE_COLUMNS:
            self.device_table.add_column(label, key=key)
        for key, label in LINE_COLUMNS:
            self.line_table.add_column(label, key=key)
        self.show()
        self.set_interval(self.refresh_s, self.show)

    def show(self) -> None:
        """Reads the source once and shows what it gives; what reading fails with goes to the status line (the view
        keeps showing what it had, and tries again at the next refresh)."""
        try:
            rows, bus, line = self.source.rows(), self.source.bus_row(), self.source.line()
            devices = self.source.devices()
        except Exception as error:  # noqa: BLE001  (a view shows its source's failure, whatever it is, and goes on)
            self.outcome(f"reading the bus failed: {error}")
            return
        self.show_devices(devices)
        self.show_line(line)
        table = self.table
        for row in rows:
            cells = {key: cell(getattr(row, key)) for key, _ in COLUMNS if key != "joint"}
            if row.name not in table.rows:
                table.add_row(row.name, *cells.values(), key=row.name)
                continue
            for key, text in cells.items():
                table.update_cell(row.name, key, text, update_width=True)
        stats = "  ".join(f"{k} {v}" for k, v in bus.stats.items())
        self.bus_text = f"bus {bus.link}: {stats}\nDC: {bus.dc}"
        self.bus_line.update(self.bus_text)

    def show_devices(self, devices: list[DeviceRow]) -> None:
        """A row per device with its channels, styled as its status's level (a device out of reach in red)."""
        table = self.device_table
        table.display = bool(devices) or bool(table.row_count)
        for row in devices:
            style = LEVEL_STYLES.get(row.level, "")
            texts = (row.name, row.slave, row.product, row.inputs, row.outputs, row.message)
            cells = [Text(t, style=style) for t in texts]
            if row.name not in table.rows:
                table.add_row(*cells, key=row.name)
                continue
            for (column, _), text in zip(DEVICE_COLUMNS, cells, strict=True):
                table.update_cell(row.name, column, text, update_width=True)

    def show_line(self, line: LineView) -> None:
        """The line's summary, and a row per port of each slave, styled as its slave's status where the port's counters
        rose lately (or the slave is out of reach)."""
        self.line_text = f"line: {line.summary}"
        self.line_summary.update(Text(self.line_text, style=LEVEL_STYLES.get(line.level, "")))
        table = self.line_table
        for row in line.rows:
            for port in row.ports:
                key = f"{row.slave}:{port.port}"
                style = LEVEL_STYLES.get(row.level, "") if port.rising or row.level == 2 else ""
                name = f"{row.slave} ({row.name})" if row.name else str(row.slave)
                texts = (
                    name,
                    str(port.port),
                    port.link,
                    port.peer,
                    port.invalid_frames,
                    port.rx_errors,
                    port.forwarded_errors,
                    port.lost_links,
                    port.window,
                )
                cells = [Text(t, style=style) for t in texts]
                if key not in table.rows:
                    table.add_row(*cells, key=key)
                    continue
                for (column, _), text in zip(LINE_COLUMNS, cells, strict=True):
                    table.update_cell(key, column, text, update_width=True)

    def selected(self) -> str | None:
        """The joint of the row under the cursor."""
        table = self.table
        if not table.row_count:
            return None
        return table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value

    def outcome(self, text: str) -> None:
        self.last_outcome = text
        self.outcome_line.update(text)

    def action_ask(self, action: str) -> None:
        joint = self.selected()
        if joint is None:
            self.outcome("no joint to ask yet")
            return

        def answered(yes: bool | None) -> None:
            if yes:
                self.outcome(f"{joint}: {action} ...")
                self.run_request(joint, action)
            else:
                self.outcome(f"{joint}: {action} not asked")

        self.push_screen(Confirm(f"{ACTION_WORDS[action].capitalize()} {joint}?"), answered)

    def action_latch(self) -> None:
        joint = self.selected()
        if joint is None:
            self.outcome("no joint to ask yet")
            return

        def chosen(choice: tuple[int, str] | None) -> None:
            if choice is None:
                self.outcome(f"{joint}: no latch armed")
                return
            channel, edge = choice
            self.push_screen(
                Confirm(f"Arm latch {channel} of {joint} on the {edge} edge?"),
                lambda yes: self.run_latch(joint, channel, edge) if yes else self.outcome(f"{joint}: no latch armed"),
            )

        self.push_screen(ChooseLatch(joint), chosen)

    @work(thread=True, exclusive=True, group="request")
    def run_request(self, joint: str, action: str) -> None:
        """Asks the source in a thread of its own (it may wait for the drive); shows the outcome."""
        try:
            text = self.source.request(joint, action)
        except Exception as e:  # noqa: BLE001  (refused or failed, the view shows why and goes on)
            text = f"refused: {e}"
        self.call_from_thread(self.outcome, text)

    @work(thread=True, exclusive=True, group="request")
    def run_latch(self, joint: str, channel: int, edge: str) -> None:
        try:
            text = self.source.arm_latch(joint, channel, edge)
        except Exception as e:  # noqa: BLE001  (refused or failed, the view shows why and goes on)
            text = f"refused: {e}"
        self.call_from_thread(self.outcome, text)
