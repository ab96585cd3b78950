"""Servers on loopback for the remote-source tests: an HTTP server that serves a folder with
faults injected per path (slowness, 5xx, truncated bodies, redirects, a changed body), and
moto's S3 server holding a bucket. No test reaches beyond 127.0.0.1."""

import contextlib
import gzip
import http.server
import os
import pathlib
import shutil
import socket
import subprocess
import threading
import time


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class FaultyHandler(http.server.SimpleHTTPRequestHandler):
    """Serves `server.root`; `server.faults[path]` changes what one path answers:
    ("status", code, times) answers `code` that many times (None: always), then serves;
    ("slow", seconds) waits before answering; ("truncate",) sends the announced length but
    half the body; ("redirect", target) answers 302 to `target`; ("body", bytes) serves
    other bytes; ("chunked",) sends the body in chunks (Transfer-Encoding: chunked, no
    Content-Length); ("close",) sends it without a length and closes the connection at its end
    (HTTP/1.0 style); ("encoded", coding) sends it gzip-compressed ("gzip") or as it is under
    another Content-Encoding name; ("partial",) answers 206 with the first half and a
    Content-Range, as a server answering a range nobody asked for would.
    `server.hits[path]` counts the requests."""

    def log_message(self, *args):
        pass

    def do_GET(self):
        path = self.path.split("?", 1)[0]
        with self.server.lock:
            self.server.hits[path] = self.server.hits.get(path, 0) + 1
            fault = self.server.faults.get(path)
            if fault and fault[0] == "status" and fault[2] is not None:
                left = fault[2] - 1
                if left <= 0:
                    self.server.faults.pop(path)
                else:
                    self.server.faults[path] = ("status", fault[1], left)
        if fault is None:
            return super().do_GET()
        kind = fault[0]
        if kind == "status":
            self.send_response(fault[1])
            self.send_header("Content-Length", "0")
            self.end_headers()
        elif kind == "slow":
            time.sleep(fault[1])
            return super().do_GET()
        elif kind == "redirect":
            self.send_response(302)
            self.send_header("Location", fault[1])
            self.send_header("Content-Length", "0")
            self.end_headers()
        elif kind == "s3list":
            if "continuation-token" in self.path:
                self.send_response(500)
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            body = (
                '<?xml version="1.0" encoding="UTF-8"?>'
                '<ListBucketResult xmlns="http://s3.amazonaws.com/doc/2006-03-01/">'
                "<Name>b</Name><Prefix>meshes/</Prefix><KeyCount>1</KeyCount>"
                "<MaxKeys>1</MaxKeys><IsTruncated>true</IsTruncated>"
                "<NextContinuationToken>page2</NextContinuationToken>"
                "<Contents><Key>meshes/a.obj</Key>"
                "<LastModified>2026-01-01T00:00:00.000Z</LastModified>"
                '<ETag>"0123"</ETag><Size>10</Size><StorageClass>STANDARD</StorageClass>'
                "</Contents></ListBucketResult>").encode()
            self.send_response(200)
            self.send_header("Content-Type", "application/xml")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)
        elif kind == "endless":
            # No length, no chunks, no end: lines of a mesh until the client hangs up.
            self.protocol_version = "HTTP/1.0"
            self.send_response(200)
            self.end_headers()
            line = b"v 0 0 0\n" * 65536
            try:
                while True:
                    self.wfile.write(line)
            except OSError:
                pass
            self.close_connection = True
        elif kind in ("chunked", "close", "encoded", "partial"):
            data = (pathlib.Path(self.server.root) / path.lstrip("/")).read_bytes()
            self.send_shaped(kind, fault, data)
        elif kind in ("truncate", "body"):
            data = (pathlib.Path(self.server.root) / path.lstrip("/")).read_bytes()
            body = fault[1] if kind == "body" else data
            self.send_response(200)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body[: len(body) // 2] if kind == "truncate" else body)
            self.wfile.flush()
            self.close_connection = True


    def send_shaped(self, kind, fault, data):
        """The body `data` framed or encoded as the fault `kind` says."""
        if kind == "partial":
            half = data[: len(data) // 2]
            self.send_response(206)
            self.send_header("Content-Range", "bytes 0-%d/%d" % (len(half) - 1, len(data)))
            self.send_header("Content-Length", str(len(half)))
            self.end_headers()
            self.wfile.write(half)
            return
        if kind == "encoded":
            body = gzip.compress(data) if fault[1] == "gzip" else data
            self.send_response(200)
            self.send_header("Content-Encoding", fault[1])
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)
            return
        if kind == "close":
            # No length and no chunks: the body ends when the connection closes.
            self.protocol_version = "HTTP/1.0"
            self.send_response(200)
            self.end_headers()
            self.wfile.write(data)
            self.wfile.flush()
            self.close_connection = True
            return
        self.protocol_version = "HTTP/1.1"
        self.send_response(200)
        self.send_header("Transfer-Encoding", "chunked")
        self.end_headers()
        for at in range(0, len(data), 1000):
            piece = data[at:at + 1000]
            self.wfile.write(b"%x\r\n%s\r\n" % (len(piece), piece))
        self.wfile.write(b"0\r\n\r\n")
        self.wfile.flush()
        self.close_connection = True


class FaultyServer:
    """A threaded HTTP server on 127.0.0.1 serving `root` with [`FaultyHandler`]."""

    def __init__(self, root):
        root = str(root)

        def handler(*a, **kw):
            return FaultyHandler(*a, directory=root, **kw)

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        self.httpd.daemon_threads = True
        # A client that gives up on a slow or truncated answer breaks the pipe: expected.
        self.httpd.handle_error = lambda request, address: None
        self.httpd.root = root
        self.httpd.faults = {}
        self.httpd.hits = {}
        self.httpd.lock = threading.Lock()
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    @property
    def url(self):
        return "http://127.0.0.1:%d" % self.httpd.server_address[1]

    @property
    def faults(self):
        return self.httpd.faults

    @property
    def hits(self):
        return self.httpd.hits

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


class MotoS3:
    """moto's S3 server (`moto_server`) on a free loopback port, with `env` for sparc3d and
    a boto3 client to fill buckets."""

    def __init__(self):
        exe = shutil.which("moto_server")
        assert exe, "moto_server is not installed (tests/python/requirements.txt: moto[server])"
        self.port = free_port()
        self.proc = subprocess.Popen(
            [exe, "-H", "127.0.0.1", "-p", str(self.port)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.time() + 30
        while True:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                break
            except OSError:
                assert self.proc.poll() is None, "moto_server exited"
                assert time.time() < deadline, "moto_server did not start in 30 s"
                time.sleep(0.1)
        self.endpoint = "http://127.0.0.1:%d" % self.port
        self.env = {
            "AWS_ENDPOINT_URL": self.endpoint,
            "AWS_ACCESS_KEY_ID": "testing",
            "AWS_SECRET_ACCESS_KEY": "testing",
            "AWS_REGION": "us-east-1",
        }
        import boto3

        self.client = boto3.client(
            "s3", endpoint_url=self.endpoint, region_name="us-east-1",
            aws_access_key_id="testing", aws_secret_access_key="testing")

    def put(self, bucket, key, data):
        try:
            self.client.create_bucket(Bucket=bucket)
        except self.client.exceptions.BucketAlreadyOwnedByYou:
            pass
        self.client.put_object(Bucket=bucket, Key=key, Body=data)

    def close(self):
        self.proc.terminate()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


@contextlib.contextmanager
def s3_environment():
    """moto's S3 server, with this process's environment set to reach it (the reader reads
    AWS_ENDPOINT_URL and the credentials from the environment) and the machine's own cloud
    settings removed; all restored at the end."""
    server = MotoS3()
    saved = {k: v for k, v in os.environ.items() if k.startswith(("AWS_", "GOOGLE_", "AZURE_"))}
    try:
        for k in saved:
            del os.environ[k]
        os.environ.update(server.env)
        yield server
    finally:
        for k in server.env:
            os.environ.pop(k, None)
        os.environ.update(saved)
        server.close()


def clean_env(extra):
    """The environment with no AWS_/GOOGLE_/AZURE_ setting of the machine's, plus `extra`."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("AWS_", "GOOGLE_", "AZURE_"))}
    env.update(extra)
    return env
