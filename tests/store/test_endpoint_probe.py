"""A refused or unknown S3 endpoint fails when the store is opened, before any request.

botocore retries a refused connection four times with backoff (about 8 s per command and per
worker); `dancedata.store.fs.check_endpoint_answers` settles it with one TCP connect first.
"""

from __future__ import annotations

import json
import socket

import pytest

from dancedata.errors import StoreError
from dancedata.store import fs
from tests.s3_server import closed_port

pytest.importorskip("s3fs")


@pytest.fixture
def clean_env(monkeypatch):
    for name in (
        "DANCEDATA_STORAGE_OPTIONS",
        "AWS_ENDPOINT_URL_S3",
        "AWS_ENDPOINT_URL",
        *fs._PROXY_VARIABLES,
    ):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("AWS_ACCESS_KEY_ID", "x")
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", "y")
    monkeypatch.setattr(fs, "_ANSWERED", set())
    return monkeypatch


def _requests(monkeypatch) -> list[str]:
    import s3fs.core

    sent: list[str] = []
    original = s3fs.core.S3FileSystem._call_s3

    async def counting(self, method, *args, **kwargs):
        sent.append(str(method))
        return await original(self, method, *args, **kwargs)

    monkeypatch.setattr(s3fs.core.S3FileSystem, "_call_s3", counting)
    return sent


def test_a_refused_endpoint_fails_at_open_without_a_request(clean_env):
    from dancedata.store.backend_fsspec import FsspecBackend

    sent = _requests(clean_env)
    endpoint = f"http://127.0.0.1:{closed_port()}"
    clean_env.setenv("AWS_ENDPOINT_URL", endpoint)
    with pytest.raises(StoreError) as caught:
        FsspecBackend("s3://bucket/store")
    assert str(caught.value) == f"cannot reach S3 endpoint {endpoint}: connection refused"
    assert sent == []


def test_the_endpoint_of_the_storage_options_is_the_one_probed(clean_env):
    endpoint = f"http://127.0.0.1:{closed_port()}"
    clean_env.setenv("AWS_ENDPOINT_URL", "http://127.0.0.1:1")
    clean_env.setenv(
        "DANCEDATA_STORAGE_OPTIONS", json.dumps({"client_kwargs": {"endpoint_url": endpoint}})
    )
    with pytest.raises(StoreError, match=f"cannot reach S3 endpoint {endpoint}: connection"):
        fs.remote_fs("s3://bucket/store")


def test_an_unknown_host_name_is_named(clean_env):
    clean_env.setenv("AWS_ENDPOINT_URL", "http://no-such-host.invalid:9000")
    with pytest.raises(StoreError) as caught:
        fs.check_endpoint_answers()
    assert str(caught.value) == (
        "cannot reach S3 endpoint http://no-such-host.invalid:9000: host name not found"
    )


def test_a_listening_endpoint_passes_and_is_probed_once(clean_env):
    with socket.create_server(("127.0.0.1", 0)) as server:
        endpoint = f"http://127.0.0.1:{server.getsockname()[1]}"
        clean_env.setenv("AWS_ENDPOINT_URL", endpoint)
        fs.check_endpoint_answers()
        conn, _ = server.accept()  # the probe's connection
        conn.close()
        server.settimeout(0.5)
        fs.check_endpoint_answers()  # remembered: no second connection
        with pytest.raises(TimeoutError):
            server.accept()
    answered = fs._ANSWERED
    assert answered == {endpoint}


def test_nothing_is_probed_through_a_proxy_or_for_the_aws_default(clean_env):
    fs.check_endpoint_answers()  # no endpoint set: AWS's own, not probed
    assert fs.explicit_endpoint() is None
    clean_env.setenv("AWS_ENDPOINT_URL", f"http://127.0.0.1:{closed_port()}")
    clean_env.setenv("HTTPS_PROXY", "http://127.0.0.1:3128")
    fs.check_endpoint_answers()  # the proxy, not us, connects to the endpoint
    answered = fs._ANSWERED
    assert answered == set()
