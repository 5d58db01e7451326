"""A real S3-compatible server (moto in server mode) on 127.0.0.1, for tests of stores on object
storage: one place for what test_remote, test_checkout and the store conformance suite need.

:func:`moto_s3` starts the server, points the AWS environment of this process (and so of CLI
subprocesses, which inherit it) at it, creates the buckets, and restores everything after.
``s3_env`` is the same as a module-scoped fixture; import it into a test module to use it.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import socket
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest

CREDENTIALS = {
    "AWS_ACCESS_KEY_ID": "testing",
    "AWS_SECRET_ACCESS_KEY": "testing",
    "AWS_DEFAULT_REGION": "us-east-1",
}


@functools.cache  # the class is built once, on first use (moto imports late)
def _s3_server_class() -> type:
    """moto's threaded server with every request but its own API sent to the S3 backend.

    moto finds the service of each request from its Host header or signature, and on the way
    lists its own package folder (about 180 ``isdir`` calls, 2.6 ms of the ~7 ms it spends on a
    GET here); these tests talk to nothing but S3, so that search is skipped. The S3 backend,
    its responses and the HTTP server are moto's own."""
    from moto.moto_server.threaded_moto_server import ThreadedMotoServer
    from moto.moto_server.werkzeug_app import (
        DomainDispatcherApplication,
        MotoRequestHandler,
        create_backend_app,
    )
    from werkzeug.serving import make_server

    class S3Dispatcher(DomainDispatcherApplication):
        def get_application(self, environ: dict[str, Any]) -> Any:
            path = environ.get("PATH_INFO", "")
            if isinstance(path, bytes):
                path = path.decode("utf-8")
            if path.startswith("/moto-api"):
                return super().get_application(environ)
            with self.lock:
                app = self.app_instances.get("s3")
                if app is None:
                    app = self.app_instances["s3"] = self.create_app("s3")
            return app

    class S3MotoServer(ThreadedMotoServer):
        def _server_entry(self) -> None:
            self._server = make_server(
                self._ip_address,
                self._port,
                S3Dispatcher(create_backend_app),
                True,
                request_handler=MotoRequestHandler,
            )
            self._server_ready_event.set()
            self._server.serve_forever()

    return S3MotoServer


def start_moto_server() -> tuple[Any, str, int]:
    """Start a moto S3 server on a free loopback port with no buckets: (server, host, port).

    ``ThreadedMotoServer`` keeps its buckets in moto's in-process backends, which every server
    started in this pytest process shares: without the reset, a bucket an earlier test module
    made still exists here (and ``s3fs.mkdir`` of it raises FileExistsError)."""
    pytest.importorskip("moto.server")
    logging.getLogger("werkzeug").setLevel(logging.ERROR)
    server = _s3_server_class()(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    host, port = server.get_host_and_port()
    reset = urllib.request.Request(f"http://{host}:{port}/moto-api/reset", method="POST")
    with urllib.request.urlopen(reset, timeout=30) as answer:
        assert answer.status == 200, answer.status
    return server, host, port


@contextlib.contextmanager
def moto_s3(*buckets: str) -> Iterator[dict[str, str]]:
    """Run a moto S3 server on a free loopback port while the block runs; yields the environment
    (credentials, region, ``AWS_ENDPOINT_URL``) that is also set in ``os.environ`` meanwhile."""
    s3fs = pytest.importorskip("s3fs")
    server, host, port = start_moto_server()
    env = {**CREDENTIALS, "AWS_ENDPOINT_URL": f"http://{host}:{port}"}
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    s3fs.S3FileSystem.clear_instance_cache()
    try:
        fs = s3fs.S3FileSystem()
        for bucket in buckets:
            fs.mkdir(bucket)
        yield env
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        s3fs.S3FileSystem.clear_instance_cache()
        server.stop()


@pytest.fixture(scope="module")
def s3_env() -> Iterator[dict[str, str]]:
    """A moto S3 server on loopback for the module; buckets are made by the tests."""
    with moto_s3() as env:
        yield env


def closed_port() -> int:
    """A loopback TCP port nothing listens on (bound, then released): connecting is refused."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])
