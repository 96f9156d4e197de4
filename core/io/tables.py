"""Reading one table file: CSV or Parquet, compressed or not, from a path or standard input.

What a file holds is decided from its content, not its name: a Parquet file
named ``.csv`` is read as Parquet, a gzip, bz2, xz or single-file zip archive
is decompressed on the fly, and ``-`` (or ``/dev/stdin``, a named pipe) is read
from the stream. CSV delimiters (comma, semicolon, tab, pipe) are found from
the header line, or from a ``sep=;`` line before it (as Excel writes and reads);
comment lines before the header (``#``, ``//``, ``%``) are skipped. Text is
UTF-8 (with or without a byte order mark), or else Windows-1252, the code page
Excel on Windows saves "CSV (Comma delimited)" in, read with a warning. Only
the columns a caller asks for are parsed, so a header of 100,000 columns costs
no more than the bytes it takes.

Every file that cannot be read raises :class:`core.errors.BGMInputError` with
one sentence naming the cause (Excel workbooks, UTF-16 text, binary junk...).
"""

from __future__ import annotations

import bz2
import codecs
import csv
import gzip
import io
import lzma
import re
import sys
import warnings
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from core.errors import BGMInputError, BGMWarning

#: First bytes of the formats recognised by content.
MAGIC = {
    b"PAR1": "parquet",
    b"\x1f\x8b": "gzip",
    b"BZh": "bz2",
    b"\xfd7zXZ\x00": "xz",
    b"(\xb5/\xfd": "zstd",
    b"PK\x03\x04": "zip",
    b"\xd0\xcf\x11\xe0": "xls",
}
#: What reading a damaged archive raises past its first bytes: a gzip or zip member whose deflate stream is
#: corrupt raises zlib.error (no OSError), a zip cut short BadZipFile, a gzip cut short EOFError.
DAMAGED = (zlib.error, zipfile.BadZipFile, gzip.BadGzipFile, EOFError, lzma.LZMAError)
#: Lines before the header starting with one of these are comments.
COMMENT_PREFIXES = ("#", "//", "%")
#: A line before the header naming the delimiter, as Excel writes and reads it (``sep=;``).
SEP_LINE = re.compile(r"sep=(.)\s*")
DELIMITERS = ",;\t|"
#: Bytes inspected to tell text from binary.
HEAD_BYTES = 64 * 1024
STDIN_NAMES = ("-",)

#: Chooses the columns to parse from the header names: returns their indices (None = all).
ColumnChooser = Callable[[list[str]], list[int] | None]


#: Excel on Windows saves "CSV (Comma delimited)" in the system code page, Windows-1252 in the
#: Americas and Western Europe: text that is not UTF-8 is read in it, with :data:`READ_AS_CP1252`.
FALLBACK_ENCODING = "cp1252"
READ_AS_CP1252 = (
    "{name} is not UTF-8 text: it was read as Windows-1252, as Excel on Windows saves 'CSV (Comma delimited)'; "
    "if accented labels look wrong, save it as 'CSV UTF-8'"
)
#: Neither UTF-8 nor Windows-1252 (which leaves bytes 0x81, 0x8D, 0x8F, 0x90 and 0x9D undefined).
NOT_TEXT = (
    "cannot read {name}: it is neither UTF-8 nor Windows-1252 text (byte {byte} on line {line}); "
    "save it as 'CSV UTF-8' (Excel: Save As, 'CSV UTF-8'); BGM reads CSV and Parquet tables"
)
#: A UTF-8 byte order mark (Excel's 'CSV UTF-8') on text that is not UTF-8: damaged, not another encoding.
NOT_UTF8 = (
    "cannot read {name}: it starts as UTF-8 text (a byte order mark) but is not UTF-8 (byte {byte} on line {line})"
)


def read_table(path: str | Path, choose: ColumnChooser | None = None) -> pd.DataFrame:
    """Read a CSV or Parquet table into a DataFrame (CSV values as strings).

    Parameters
    ----------
    path : path-like
        A file, ``-`` for standard input, or a pipe or device to read to its end.
    choose : callable, optional
        ``choose(header) -> indices`` of the columns to parse; all when omitted.

    Returns
    -------
    DataFrame
        ``attrs["first_data_line"]`` is the file line of the first row (1-based),
        and :func:`data_lines` each row's, so messages can point at lines as an
        editor shows them. CSV rows whose every field is blank (``,,,,`` as
        spreadsheets export them) are left out, with a warning.
    """
    name, data = _content(path)
    kind = _kind(name, data)
    if kind == "parquet":
        return _read_parquet(name, data, choose)
    opener = _opener(name, data, kind)
    try:  # the damage of an archive shows wherever its stream is read, not only in its first bytes
        with opener() as fh:
            head = fh.read(8)
        if head.startswith(b"PAR1"):  # a compressed Parquet file
            with opener() as fh:
                return _read_parquet(name, fh.read(), choose)
        return _read_csv(name, opener, choose)
    except DAMAGED as exc:
        raise BGMInputError(f"cannot read {name}: the compressed data is damaged ({_one_line(exc)})") from None


def data_lines(frame: pd.DataFrame) -> np.ndarray:
    """The file line (1-based) of each row of a table :func:`read_table` read (blank lines skipped)."""
    lines = frame.attrs.get("lines")
    if lines is not None and len(lines) == len(frame):
        return np.asarray(lines)
    return int(frame.attrs.get("first_data_line", 2)) + np.arange(len(frame))


def display_name(path: str | Path) -> str:
    """How messages name an input (standard input for ``-``)."""
    return "standard input" if str(path) in STDIN_NAMES else repr(str(path))


# --------------------------------------------------------------------------- what the file is


def _built_from(folder: Path) -> str:
    """What to open instead of a ``bgm build`` folder: the table it was built from (its ``summary.json``'s ``input``).

    ``bgm demo`` ends with "open it in 3D with: bgm view", and ``bgm view bgm-demo`` was refused with no word
    of the table the folder holds the model of.
    """
    import json

    try:
        source = json.loads((folder / "summary.json").read_text(encoding="utf-8")).get("input")
    except (OSError, ValueError, AttributeError):
        return ""
    return f" (it holds a model built from {source}: give that table)" if isinstance(source, str) else ""


def _content(path: str | Path) -> tuple[str, Path | bytes]:
    """The input's display name and either its path (regular files) or all its bytes (streams)."""
    name = display_name(path)
    if str(path) in STDIN_NAMES:
        if sys.stdin is None or sys.stdin.isatty():
            raise BGMInputError("no table on standard input: pipe one in, e.g. bgm contours - < holes.csv")
        data = sys.stdin.buffer.read()
        if not data:
            raise BGMInputError("standard input is empty: nothing was piped in")
        return name, data
    path = Path(path)
    if not path.exists():
        raise BGMInputError(f"input file {name} does not exist")
    if path.is_dir():
        raise BGMInputError(f"input {name} is a directory, not a CSV or Parquet file{_built_from(path)}")
    try:
        if path.is_file():
            if path.stat().st_size == 0:
                raise BGMInputError(f"input file {name} is empty")
            return name, path
        with open(path, "rb") as fh:  # a pipe or device: read it to its end once
            data = fh.read()
    except OSError as exc:
        raise BGMInputError(f"cannot read {name}: {exc.strerror or exc}") from None
    if not data:
        raise BGMInputError(f"input {name} is empty")
    return name, data


def _head(data: Path | bytes, n: int = 8) -> bytes:
    if isinstance(data, bytes):
        return data[:n]
    try:
        with open(data, "rb") as fh:
            return fh.read(n)
    except OSError as exc:
        raise BGMInputError(f"cannot read {str(data)!r}: {exc.strerror or exc}") from None


def _kind(name: str, data: Path | bytes) -> str:
    """``parquet``, ``csv`` or a compression; refuses spreadsheets and unsupported archives."""
    head = _head(data)
    kind = next((k for magic, k in MAGIC.items() if head.startswith(magic)), "csv")
    if kind == "xls":
        raise BGMInputError(f"cannot read {name}: it is an Excel workbook; save the sheet as CSV")
    if kind == "zip":
        members = _zip_members(name, data)
        if any(m.filename.startswith("xl/") for m in members):
            raise BGMInputError(f"cannot read {name}: it is an Excel workbook; save the sheet as CSV")
        if len(members) != 1:
            raise BGMInputError(
                f"cannot read {name}: a zip archive must hold exactly one table, it holds {len(members)}"
            )
        if members[0].flag_bits & 0x1:  # zipfile would ask for a password it has no way to be given
            raise BGMInputError(f"cannot read {name}: the zip archive is encrypted; extract the table first")
    if kind == "zstd":
        try:
            import zstandard  # noqa: F401
        except ImportError:
            raise BGMInputError(
                f"cannot read {name}: it is zstd-compressed; decompress it first (or pip install zstandard)"
            ) from None
    suffix = data.suffix.lower() if isinstance(data, Path) else ""
    if kind == "csv" and suffix in (".parquet", ".pq"):
        warnings.warn(f"{name} is named {suffix} but is not Parquet; reading it as CSV text", BGMWarning, stacklevel=4)
    return kind


def _zip_members(name: str, data: Path | bytes) -> list[zipfile.ZipInfo]:
    """The files a zip archive holds (folders and macOS resource forks left out).

    Raises
    ------
    BGMInputError
        The archive cannot be opened: cut short (a download or copy that did not finish,
        which loses the directory at its end) or damaged.
    """
    try:
        with zipfile.ZipFile(data if isinstance(data, Path) else io.BytesIO(data)) as z:
            infos = z.infolist()
    except (zipfile.BadZipFile, EOFError, ValueError) as exc:
        raise BGMInputError(
            f"cannot read {name}: the zip archive is damaged or incomplete ({_one_line(exc)})"
        ) from None
    return [i for i in infos if not i.filename.endswith("/") and not i.filename.startswith("__MACOSX")]


def _opener(name: str, data: Path | bytes, kind: str) -> Callable[[], io.BufferedIOBase]:
    """A function returning a fresh binary stream of the (decompressed) content."""

    def raw():
        return open(data, "rb") if isinstance(data, Path) else io.BytesIO(data)

    if kind == "csv":
        return raw
    if kind == "zip":

        def unzip():
            z = zipfile.ZipFile(raw())
            member = next(m for m in z.namelist() if not m.endswith("/") and not m.startswith("__MACOSX"))
            return z.open(member)

        return unzip
    if kind == "zstd":
        import zstandard

        return lambda: zstandard.ZstdDecompressor().stream_reader(raw(), closefd=True)
    module = {"gzip": gzip, "bz2": bz2, "xz": lzma}[kind]
    return lambda: module.open(raw())


# --------------------------------------------------------------------------- Parquet


def _read_parquet(name: str, data: Path | bytes, choose: ColumnChooser | None) -> pd.DataFrame:
    import pyarrow as pa
    import pyarrow.parquet as pq

    source = data if isinstance(data, Path) else pa.BufferReader(data)
    try:
        names = [str(n) for n in pq.read_schema(source).names]
        wanted = choose(names) if choose else None
        table = pq.read_table(source, columns=None if wanted is None else [names[i] for i in wanted])
        frame = table.to_pandas()
    except BGMInputError:
        raise
    except Exception as exc:  # pyarrow raises many types for damaged files
        raise BGMInputError(f"cannot read {name} as Parquet: {_one_line(exc)}") from None
    frame.attrs["first_data_line"] = 2
    return frame


# --------------------------------------------------------------------------- CSV


def _read_csv(name: str, opener, choose: ColumnChooser | None) -> pd.DataFrame:
    """The CSV table: UTF-8 text, else Windows-1252 text (with a warning), else an error naming the byte."""
    with opener() as fh:
        head = _decompressed(name, fh.read, HEAD_BYTES)
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise BGMInputError(f"cannot read {name}: it is UTF-16 text, not UTF-8; save it as UTF-8 CSV")
    if b"\x00" in head:
        raise BGMInputError(f"cannot read {name}: it looks binary; BGM reads CSV and Parquet (.parquet) tables")
    if _is_utf8(head, final=len(head) < HEAD_BYTES):  # else no need to parse the file as UTF-8 to find out
        try:
            return _parse_csv(name, opener, choose, "utf-8-sig")
        except UnicodeDecodeError:
            pass
    if head.startswith(codecs.BOM_UTF8):
        raise BGMInputError(NOT_UTF8.format(name=name, **_bad_byte(opener, "utf-8-sig")))
    try:
        frame = _parse_csv(name, opener, choose, FALLBACK_ENCODING)
    except UnicodeDecodeError:
        raise BGMInputError(NOT_TEXT.format(name=name, **_bad_byte(opener, FALLBACK_ENCODING))) from None
    warnings.warn(READ_AS_CP1252.format(name=name), BGMWarning, stacklevel=4)
    frame.attrs["encoding"] = FALLBACK_ENCODING
    return frame


def _is_utf8(data: bytes, final: bool) -> bool:
    """Whether ``data`` is UTF-8 (a sequence cut at its end is fine unless ``final``)."""
    try:
        codecs.getincrementaldecoder("utf-8")().decode(data, final=final)
    except UnicodeDecodeError:
        return False
    return True


def _bad_byte(opener, encoding: str) -> dict[str, str | int]:
    """The first byte ``encoding`` cannot decode (``0x81``) and its file line (1-based), for messages."""
    decoder = codecs.getincrementaldecoder(encoding)()
    line, chunk = 1, b""
    with opener() as fh:
        while chunk := fh.read(1 << 20):
            try:
                line += decoder.decode(chunk).count("\n")
            except UnicodeDecodeError as exc:
                # The decoder holds back at most the few bytes of a cut UTF-8 sequence: count the chunk's own.
                start = max(exc.start - len(exc.object) + len(chunk), 0)
                return {"byte": f"0x{chunk[start]:02X}", "line": line + chunk[:start].count(b"\n")}
    return {"byte": "?", "line": line}


def _parse_csv(name: str, opener, choose: ColumnChooser | None, encoding: str) -> pd.DataFrame:
    """The CSV table as ``encoding`` text; raises ``UnicodeDecodeError`` when the bytes are not."""
    skip, header_line, given_sep = _header_line(name, opener, encoding)
    sep = given_sep or _delimiter(header_line)
    try:
        header = next(csv.reader([header_line.rstrip("\r\n")], delimiter=sep))
    except csv.Error as exc:
        raise BGMInputError(f"cannot read the header of {name}: {_one_line(exc)}") from None
    wanted = choose(header) if choose else None
    try:
        with opener() as fh:
            frame = pd.read_csv(
                fh,
                sep=sep,
                dtype=str,
                keep_default_na=False,
                encoding=encoding,
                skiprows=skip,
                usecols=None if wanted is None else sorted(wanted),
                index_col=False,
            )
    except UnicodeDecodeError:
        raise
    except Exception as exc:  # pandas raises many types for unreadable files
        raise BGMInputError(f"cannot read {name} as CSV: {_parser_message(exc, skip)}") from None
    # usecols makes pandas drop a row's fields beyond the header without a word: refuse such rows then.
    lines, empty = _scan_rows(name, opener, sep, skip, len(header) if wanted is not None else None, encoding)
    frame.columns = [header[i] for i in sorted(wanted)] if wanted is not None else header[: frame.shape[1]]
    if len(lines) == len(frame):  # else the csv module split records unlike pandas: number rows as before
        frame = _without_empty_rows(name, frame, lines, empty)
    frame.attrs["first_data_line"] = skip + 2
    frame.attrs["delimiter"] = sep
    return frame


def _without_empty_rows(name: str, frame: pd.DataFrame, lines: np.ndarray, empty: np.ndarray) -> pd.DataFrame:
    """``frame`` without its rows whose every field is blank (said in a warning), its rows' lines in attrs."""
    if empty.any():
        warnings.warn(
            f"{name}: {int(empty.sum())} empty row(s) (every field blank) were skipped, on line(s) "
            f"{', '.join(map(str, lines[empty][:10]))}{' ...' if empty.sum() > 10 else ''}",
            BGMWarning,
            stacklevel=6,
        )
        frame = frame[~empty].reset_index(drop=True)
    frame.attrs["lines"] = lines[~empty]
    return frame


def _scan_rows(
    name: str, opener, sep: str, skip: int, n_fields: int | None, encoding: str = "utf-8-sig"
) -> tuple[np.ndarray, np.ndarray]:
    """Each data row's first file line and whether its every field is blank, as pandas sees the rows.

    Python's C ``csv`` reader, one more pass (about a second per million
    rows). Lines pandas skips (empty or only spaces) are no rows, so a row
    after them is still named by its own line. With ``n_fields``, rows with
    a non-empty field past the header's are refused: an unquoted delimiter
    shifted them.
    """
    limit = csv.field_size_limit(sys.maxsize)  # pandas read these fields already, however long
    lines: list[int] = []
    empty: list[bool] = []
    try:
        with opener() as fh:
            text = io.TextIOWrapper(fh, encoding=encoding, newline="")
            rows = csv.reader(text, delimiter=sep)
            end = 0  # the last line of the previous record
            for row in rows:
                start, end = end + 1, rows.line_num
                if end <= skip + 1 or not any(f.strip() for f in row) and len(row) <= 1:
                    continue  # comments, the header, and lines pandas skips as blank
                if n_fields is not None and len(row) > n_fields and any(f.strip() for f in row[n_fields:]):
                    raise BGMInputError(
                        f"cannot read {name} as CSV: line {end} has {len(row)} fields where the header has "
                        f"{n_fields}; quote fields that hold the delimiter {sep!r}"
                    )
                lines.append(start)
                empty.append(not any(f.strip() for f in row))
    finally:
        csv.field_size_limit(limit)
    return np.array(lines, dtype=np.int64), np.array(empty, dtype=bool)


def _decompressed(name: str, read, n: int) -> bytes:
    try:
        return read(n)
    except (OSError, EOFError, lzma.LZMAError, zipfile.BadZipFile) as exc:
        raise BGMInputError(f"cannot read {name}: the compressed data is damaged ({_one_line(exc)})") from None


def _delimiter(header_line: str) -> str:
    """The delimiter a header line uses: the most frequent of :data:`DELIMITERS`, else a comma."""
    return max(DELIMITERS, key=header_line.count) if any(d in header_line for d in DELIMITERS) else ","


def _header_line(name: str, opener, encoding: str = "utf-8-sig") -> tuple[int, str, str | None]:
    """Number of comment, blank or ``sep=`` lines before the header, the header line, and the delimiter a
    ``sep=`` line names (None without one). Raises ``UnicodeDecodeError`` when they are not ``encoding`` text."""
    sep = None
    try:
        with opener() as fh:
            text = io.TextIOWrapper(fh, encoding=encoding, errors="strict", newline="")
            for skip, line in enumerate(text):
                given = SEP_LINE.fullmatch(line.strip("\r\n")) if sep is None else None
                if given:
                    sep = given.group(1)
                elif line.strip() and not line.lstrip().startswith(COMMENT_PREFIXES):
                    return skip, line, sep
    except (OSError, EOFError, lzma.LZMAError) as exc:
        raise BGMInputError(f"cannot read {name}: the compressed data is damaged ({_one_line(exc)})") from None
    raise BGMInputError(f"cannot read {name}: it holds no table, only blank or comment lines")


_FIELDS = re.compile(r"Expected (\d+) fields in line (\d+), saw (\d+)")


def _parser_message(exc: Exception, skip: int) -> str:
    found = _FIELDS.search(str(exc))
    if found:
        expected, line, saw = found.groups()
        return f"line {int(line) + skip} has {saw} fields where the header has {expected}"
    return _one_line(exc)


def _one_line(exc) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 200 else text[:200] + "..."
