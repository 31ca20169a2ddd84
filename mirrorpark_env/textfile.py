"""Reading the text files users write (layouts, case files, configs, notes): anything wrong
with one becomes a ``ValueError`` of one line that names the file.

UTF-8 with or without a byte-order mark (spreadsheets write one); JSON, YAML and CSV
parsed with their limits turned into such errors: nesting too deep for the parser,
integers too long to convert, CSV fields over the csv module's limit.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any


def read_text(path: str | Path, what: str = "file") -> str:
    """The file's text (UTF-8, a leading byte-order mark dropped)."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as err:
        raise ValueError(f"{p}: cannot read {what} ({err.strerror})") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise ValueError(f"{p}: not UTF-8 text (byte {err.start})") from None


def parse_json(text: str, path: str | Path, **hooks: Callable) -> Any:
    """``json.loads(text)``; its errors and limits named with ``path``."""
    try:
        return json.loads(text, **hooks)
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not valid JSON: {err}") from None
    except RecursionError:
        raise ValueError(f"{path}: JSON nested too deeply to read") from None
    except ValueError as err:  # an integer of more digits than Python converts
        raise ValueError(f"{path}: JSON not readable: {err}") from None


def parse_yaml(text: str, path: str | Path) -> Any:
    """``yaml.safe_load(text)``; its errors and limits named with ``path``."""
    import yaml

    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not valid YAML: {' '.join(str(err).split())}") from None
    except RecursionError:
        raise ValueError(f"{path}: YAML nested too deeply to read") from None
    except ValueError as err:
        raise ValueError(f"{path}: YAML not readable: {err}") from None


def csv_rows(text: str, path: str | Path) -> Iterator[list[str]]:
    """The rows of CSV ``text``, one at a time; a malformed file or an over-long field named
    with ``path`` and the line."""
    reader = csv.reader(io.StringIO(text, newline=""))
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as err:
            raise ValueError(f"{path}: line {reader.line_num}: not readable as CSV: {err}") from None
        yield row
