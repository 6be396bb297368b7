"""``pfbench sweep --executor dask --scheduler ADDR``: a malformed address, a port where nothing
listens, an HTTP server and a service that answers with foreign bytes are each one line and exit 2,
before the sweep touches a file. Loopback addresses only; the handshake limit is shortened to keep
the tests fast (the default is checked to leave room under the 15 s the issue asks for)."""
import http.server
import socket
import threading

import pytest
from click.testing import CliRunner

from pfbench import cli
from pfbench.sweep import runner

SWEEP = ["sweep", "--model", "ob1", "--particles", "10", "--runs", "1", "--steps", "3", "--backend", "numpy",
         "--quiet", "--executor", "dask"]


def _one_line(tmp_path, address, *needles):
    out = tmp_path / "s.jsonl"
    r = CliRunner().invoke(cli.main, [*SWEEP, "--scheduler", address, "--out", str(out)])
    err = r.stderr.strip()
    assert r.exit_code == 2, (r.exit_code, r.output)
    assert err.startswith("error: --scheduler") and "\n" not in err and "Traceback" not in err, err
    assert all(n in err for n in needles), err
    assert "memory" not in err
    assert not list(tmp_path.iterdir())  # refused before the store (or its lock) was created
    return err


@pytest.fixture
def short_handshake(monkeypatch):
    monkeypatch.setattr(runner, "HANDSHAKE_S", 1.0)


def test_the_default_handshake_limit_leaves_room_under_15_s():
    # Catches: a limit raised past what "one line within 15 s" allows (Python start-up included).
    assert runner.HANDSHAKE_S <= 10


@pytest.mark.parametrize("address", ["foo", "tcp://", "tcp://127.0.0.1", "tcp://127.0.0.1:99999",
                                     "http://127.0.0.1:8786", "tcp://127.0.0.1:80/x", "tcp://a b:1"])
def test_a_malformed_address_is_one_line(tmp_path, address):
    # Before: a traceback from distributed. Catches: connecting without validating the address.
    _one_line(tmp_path, address, "not a Dask scheduler address", "tcp://HOST:PORT")


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):  # the server's log would land in the captured stderr
        pass


def _serve(handler_cls):
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler_cls)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    return srv


def test_an_http_server_on_the_port_is_one_line(tmp_path, short_handshake):
    # Before: the client waited 695 s for a handshake the HTTP server never sends. Catches: relying
    # on distributed's connect timeout, which does not cover the handshake (this test would hang).
    srv = _serve(_Quiet)
    try:
        _one_line(tmp_path, f"tcp://127.0.0.1:{srv.server_address[1]}", "no Dask scheduler answered")
    finally:
        srv.shutdown()
        srv.server_close()


def test_a_service_answering_foreign_bytes_is_not_out_of_memory(tmp_path, short_handshake):
    # Before: its reply was read as a frame length of exabytes: "out of memory; use fewer
    # particles". Catches: letting the decoder's MemoryError (or any error of it) through.
    lsn = socket.socket()
    lsn.bind(("127.0.0.1", 0))
    lsn.listen()

    def answer():
        conn, _ = lsn.accept()
        conn.sendall(b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\n\r\n")
        conn.recv(1 << 16)
        conn.close()

    threading.Thread(target=answer, daemon=True).start()
    try:
        _one_line(tmp_path, f"127.0.0.1:{lsn.getsockname()[1]}", "not a Dask scheduler")
    finally:
        lsn.close()


def test_a_port_where_nothing_listens_is_one_line(tmp_path, short_handshake):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # a free port: connections are refused
    _one_line(tmp_path, f"tcp://127.0.0.1:{port}", "cannot reach")
