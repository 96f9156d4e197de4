"""File > Open blastholes' reading options: units, columns and bench height, as ``bgm view``'s options give them.

A table in feet with low benches, or whose geozones are in a column no alias
finds, can only be read right when told; the dialog offers the table's
columns and starts from the options the current input was read with.
"""

from __future__ import annotations

from pathlib import Path

from qtpy import QtWidgets

from core.errors import BGMInputError

#: Units as the dialog offers them -> ``read_blastholes``'s ``length_unit`` (``None``: guessed).
UNITS = {"guess from the bench height": None, "metres (m)": "m", "feet (ft)": "ft"}
#: The column roles, their labels and :func:`core.io.blastholes.read_blastholes` keywords.
COLUMNS = {
    "x": "x (easting) column",
    "y": "y (northing) column",
    "z": "z (elevation) column",
    "geozone": "geozone column",
}
AUTO_COLUMN = "(found by name)"


class _Header(BGMInputError):
    """Stops reading a table at its header (raised by the column chooser, which the reader lets through)."""


def table_header(path: str | Path) -> list[str]:
    """The column names of a blasthole table (``[]`` when it cannot be read: the reader says why on opening)."""
    from core.io.tables import read_table

    def stop(header: list[str]) -> list[int]:
        raise _Header(list(header))

    try:
        read_table(path, stop)
    except _Header as header:
        return [str(c) for c in header.args[0]]
    except Exception:  # the reading itself names the problem when the table is opened
        return []
    return []


class ReadOptionsDialog(QtWidgets.QDialog):
    """Units, column names and bench height to read ``path`` with, starting from ``current`` (read keywords)."""

    def __init__(self, parent, path: str | Path, current: dict | None = None):
        super().__init__(parent)
        current = current or {}
        self.setWindowTitle(f"Read {Path(path).name}")
        form = QtWidgets.QFormLayout(self)
        self.units = QtWidgets.QComboBox()
        self.units.addItems(list(UNITS))
        given = {v: k for k, v in UNITS.items()}.get(current.get("length_unit"))
        if given:
            self.units.setCurrentText(given)
        form.addRow("length unit", self.units)
        header = table_header(path)
        self.columns: dict[str, QtWidgets.QComboBox] = {}
        for role, label in COLUMNS.items():
            box = QtWidgets.QComboBox()
            box.setEditable(True)
            box.addItems([AUTO_COLUMN, *header])
            # a column of the current input is kept only if this table has it
            if current.get(role) in header:
                box.setCurrentText(current[role])
            form.addRow(label, box)
            self.columns[role] = box
        self.bench_height = QtWidgets.QLineEdit()
        self.bench_height.setPlaceholderText("detected from z")
        if current.get("bench_height") is not None:
            self.bench_height.setText(f"{current['bench_height']:g}")
        form.addRow("bench height (input units)", self.bench_height)
        buttons = QtWidgets.QDialogButtonBox(
            QtWidgets.QDialogButtonBox.StandardButton.Ok | QtWidgets.QDialogButtonBox.StandardButton.Cancel
        )
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def options(self) -> dict:
        """The options chosen, as :func:`core.io.blastholes.read_blastholes` takes them (those left automatic left out).

        Raises
        ------
        BGMInputError
            If the bench height is not a positive number.
        """
        out: dict = {}
        unit = UNITS[self.units.currentText()]
        if unit:
            out["length_unit"] = unit
        for role, box in self.columns.items():
            text = box.currentText().strip()
            if text and text != AUTO_COLUMN:
                out[role] = text
        text = self.bench_height.text().strip()
        if text:
            try:
                height = float(text)
            except ValueError:
                height = float("nan")
            if not height > 0 or height == float("inf"):
                raise BGMInputError(f"bench height {text!r} is not a positive number")
            out["bench_height"] = height
        return out
