"""Replay every log of the public corpus and write its table into ``docs/logs.md``.

The logs are those of ``tests/data/corpus/manifest.toml``
(:mod:`estimator.analysis.log_corpus`): the committed fixtures from ``tests/data/corpus/``,
the others from a cache folder (``--cache``, default ``out/corpus``, laid out as
``owner+name/path``), filled with ``--fetch`` from raw.githubusercontent.com at each log's
commit; every file's sha256 is checked against the manifest. The table between the
``corpus-table`` markers of ``docs/logs.md`` is replaced, with the counts under it; a log
absent from the cache is listed as not fetched. Exit 1 when a replay raised anything but a
user error. Run: ``python scripts/log_corpus.py [--fetch]``.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import urllib.parse
import urllib.request
from collections.abc import Sequence
from pathlib import Path

from estimator.analysis.log_corpus import (
    FLEW_MIN_S,
    TRACEBACK,
    CorpusLog,
    Outcome,
    load_manifest,
    log_outcome,
)

REPO = Path(__file__).resolve().parent.parent
CORPUS = REPO / "tests" / "data" / "corpus"
MANIFEST = CORPUS / "manifest.toml"
DOC = REPO / "docs" / "logs.md"
BEGIN, END = "<!-- corpus-table begin -->", "<!-- corpus-table end -->"
RAW_URL = "https://raw.githubusercontent.com/{repo}/{commit}/{path}"
FETCH_TIMEOUT_S = 60.0
NOT_FETCHED = "not fetched (run with --fetch)"


def local_path(log: CorpusLog, cache: Path) -> Path:
    """The committed fixture, else the log's place in ``cache``."""
    return CORPUS / log.fixture if log.fixture else cache / log.cache_name


def fetch(log: CorpusLog, dest: Path) -> None:
    """Download the log at its commit into ``dest``, refusing content of another sha256."""
    url = RAW_URL.format(repo=log.repo, commit=log.commit, path=urllib.parse.quote(log.path))
    with urllib.request.urlopen(url, timeout=FETCH_TIMEOUT_S) as response:
        data = response.read()
    if hashlib.sha256(data).hexdigest() != log.sha256:
        raise SystemExit(f"{url}: content differs from the manifest's sha256")
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_bytes(data)


def outcome_of(log: CorpusLog, cache: Path, download: bool) -> Outcome | None:
    """The replay outcome of one log; None when it is not on disk (nor fetched)."""
    path = local_path(log, cache)
    if not path.is_file() and download:
        fetch(log, path)
    if not path.is_file():
        return None
    if hashlib.sha256(path.read_bytes()).hexdigest() != log.sha256:
        raise SystemExit(f"{path}: content differs from the manifest's sha256")
    return log_outcome(path)


def table_row(log: CorpusLog, outcome: Outcome | None) -> str:
    """One markdown row: log, source, firmware, format, kind, licence, flown s (or "heights
    astray", :class:`~estimator.analysis.log_corpus.FlightWatch`), outcome."""
    name = f"`{log.fixture}` (fixture)" if log.fixture else f"`{log.path}`"
    source = f"{log.repo}@{log.commit[:7]}"
    if outcome is None:
        cells = ["–", "–", "–", NOT_FETCHED]
    else:
        firmware = outcome.firmware or "not stated"
        flew = "heights astray" if outcome.flew_s is None else f"{outcome.flew_s:.0f}"
        cells = [firmware, outcome.format, flew, outcome.text()]
    text = [name, source, cells[0], cells[1], log.kind, log.licence, cells[2], cells[3]]
    return "| " + " | ".join(cell.replace("|", "/") for cell in text) + " |"


def counts(outcomes: Sequence[Outcome | None]) -> str:
    """The summary line under the table."""
    done = [o for o in outcomes if o is not None]
    flew = sum(o.reason is None for o in done)
    tracebacks = sum(o.reason is not None and o.reason.startswith(TRACEBACK) for o in done)
    vague = sum(o.reason is not None and "no battery telemetry" in o.reason for o in done)
    flown = [o for o in done if o.flew]
    measured = [o for o in flown if o.current]
    grounded = sum(o.reason is not None for o in measured)
    return (
        f"{len(outcomes)} logs, {len(done)} replayed: {flew} airborne, "
        f"{len(done) - flew} with a reason, {tracebacks} tracebacks, "
        f"{vague} without a named reason. {len(flown)} logs show a flight (at least "
        f'{FLEW_MIN_S:.0f} s armed above 1 m by their own heights, column "flown s"), '
        f"{len(measured)} of them with a measured current: {grounded} of those not airborne."
    )


def write_table(rows: list[str], summary: str) -> None:
    text = DOC.read_text()
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    header = [
        "| log | source | firmware | format | kind | licence | flown s | outcome |",
        "|---|---|---|---|---|---|---:|---|",
    ]
    block = "\n".join([BEGIN, *header, *rows, "", summary, END])
    DOC.write_text(head + block + tail)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", type=Path, default=REPO / "out" / "corpus")
    parser.add_argument("--fetch", action="store_true", help="download logs absent from --cache")
    args = parser.parse_args(argv)
    logs = load_manifest(MANIFEST)
    outcomes = []
    for log in logs:
        outcome = outcome_of(log, args.cache, args.fetch)
        outcomes.append(outcome)
        print(f"{log.repo}/{log.path}: {'–' if outcome is None else outcome.text()}", flush=True)
    summary = counts(outcomes)
    write_table([table_row(log, o) for log, o in zip(logs, outcomes, strict=True)], summary)
    print(summary)
    failed = any(o is not None and o.reason and o.reason.startswith(TRACEBACK) for o in outcomes)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
