"""rsfapp.fsqueue: the filesystem broker under concurrent producers and consumers.

Stock kombu creates a message file under its final name and then writes it, so a
consumer could read it half-written (JSONDecodeError, worker stops).  These tests run
real kombu connections on real folders: several producer processes publish while several
consumer processes read, and every message must arrive intact exactly once.
"""

from __future__ import annotations

import json
import logging
import multiprocessing as mp
import os
from pathlib import Path
from queue import Empty
from typing import Any

import pytest
from kombu import Connection

from rsfapp.config import Settings
from rsfapp.fsqueue import MESSAGE_SUFFIX, PARTIAL_SUFFIX, TRANSPORT_PATH, Transport
from rsfapp.queue import make_app

#: kombu keeps declared bindings in process-global state (the real app uses one folder),
#: so each test gets its own queue name to bind it in its own tmp folder.
QUEUE = "fsq-concurrent"
N_PRODUCERS = 4
N_CONSUMERS = 3
N_PER_PRODUCER = 250
#: Payload size [bytes]: large enough that one write is many pages, so a reader racing
#: a non-atomic writer sees a torn file often (stock kombu failed 6 of 14 runs here).
PAD = 48 * 1024
STOP = "stop"


def _options(base: Path) -> dict[str, object]:
    return Settings(data_dir=base).broker_transport_options


def _connection(base: Path) -> Connection:
    return Connection("filesystem://", transport=Transport, transport_options=_options(base))


def _body(producer: int, i: int) -> dict[str, Any]:
    # the pad depends on (producer, i), so a mixed-up or truncated body cannot pass
    return {"p": producer, "i": i, "pad": f"{producer}:{i}:" * (PAD // 8)}


def _produce(base: str, producer: int) -> None:
    with _connection(Path(base)) as conn:
        q = conn.SimpleQueue(QUEUE)
        for i in range(N_PER_PRODUCER):
            q.put(_body(producer, i))
        q.close()


def _consume(base: str, out: Any) -> None:
    got: list[tuple[int, int]] = []
    errors: list[str] = []
    try:
        with _connection(Path(base)) as conn:
            q = conn.SimpleQueue(QUEUE)
            while True:
                try:
                    m = q.get(block=True, timeout=60)
                except Empty:
                    errors.append("timed out waiting for a message")
                    break
                body = m.payload
                m.ack()
                if body == STOP:
                    break
                if body != _body(body["p"], body["i"]):
                    errors.append(f"corrupt body for {body['p']}:{body['i']}")
                got.append((body["p"], body["i"]))
            q.close()
    except Exception as exc:  # noqa: BLE001 - any consumer error fails the test
        errors.append(f"{type(exc).__name__}: {exc}")
    out.put((got, errors))


def test_concurrent_producers_and_consumers_exactly_once(tmp_path: Path) -> None:
    ctx = mp.get_context("fork")
    out = ctx.Queue()
    consumers = [
        ctx.Process(target=_consume, args=(str(tmp_path), out)) for _ in range(N_CONSUMERS)
    ]
    producers = [ctx.Process(target=_produce, args=(str(tmp_path), p)) for p in range(N_PRODUCERS)]
    for proc in consumers + producers:
        proc.start()
    for proc in producers:
        proc.join(120)
        assert proc.exitcode == 0
    # one stop message per consumer, published after every data message: consumers scan
    # the folder in name (= time) order, so a stop is taken only once no data file is left
    with _connection(tmp_path) as conn:
        q = conn.SimpleQueue(QUEUE)
        for _ in consumers:
            q.put(STOP)
        q.close()
    results = [out.get(timeout=180) for _ in consumers]
    for proc in consumers:
        proc.join(30)
        assert proc.exitcode == 0
    received = [x for got, _ in results for x in got]
    errors = [e for _, errs in results for e in errs]
    assert errors == []
    expected = {(p, i) for p in range(N_PRODUCERS) for i in range(N_PER_PRODUCER)}
    assert len(received) == len(expected)  # nothing twice
    assert set(received) == expected  # nothing lost
    broker = tmp_path / "broker"
    assert os.listdir(broker / "queue") == []  # no partial file left behind
    assert os.listdir(broker / "quarantine") == []


def test_torn_file_is_quarantined_not_raised(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A half-written file (as an old writer leaves it) is moved aside with a warning and
    the next good message is delivered; stock kombu raises JSONDecodeError here."""
    QUEUE = "fsq-torn"
    with _connection(tmp_path) as conn:
        q = conn.SimpleQueue(QUEUE)
        queue_dir = tmp_path / "broker" / "queue"
        full = json.dumps({"body": "x" * 100})
        torn = queue_dir / f"0000_torn.{QUEUE}{MESSAGE_SUFFIX}"
        torn.write_text(full[: len(full) // 2])
        q.put({"ok": 1})
        with caplog.at_level(logging.WARNING, logger="rsfapp.fsqueue"):
            m = q.get(block=False)
        assert m.payload == {"ok": 1}
        m.ack()
        assert (tmp_path / "broker" / "quarantine" / torn.name).read_text() == full[
            : len(full) // 2
        ]
        assert any(torn.name in r.getMessage() for r in caplog.records)
        with pytest.raises(Empty):
            q.get(block=False)
        q.close()


def test_partial_file_is_invisible(tmp_path: Path) -> None:
    """A message still being written (``.part``) is neither counted nor delivered."""
    QUEUE = "fsq-partial"
    with _connection(tmp_path) as conn:
        q = conn.SimpleQueue(QUEUE)
        partial = tmp_path / "broker" / "queue" / f"0000_x.{QUEUE}{MESSAGE_SUFFIX}{PARTIAL_SUFFIX}"
        partial.write_text('{"trunc')
        assert q.qsize() == 0
        with pytest.raises(Empty):
            q.get(block=False)
        assert partial.exists()
        q.close()


def test_app_uses_the_safe_transport(tmp_path: Path) -> None:
    app = make_app(Settings(data_dir=tmp_path))
    assert app.conf.broker_transport == TRANSPORT_PATH
    with app.connection_for_write() as conn:
        assert isinstance(conn.transport, Transport)
