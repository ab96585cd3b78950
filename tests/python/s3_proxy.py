"""A reverse proxy on loopback in front of an S3 server (moto), for the bucket-job tests and
benchmark: it counts the requests by method and by what they touch, and injects faults per
rule: answer a status (503 SlowDown) a number of times, cut the connection after part of a
request's body (a network cut in the middle of an upload), hold a request back for a while,
or go down: every connection closed unanswered for some seconds (a store restarting)."""

import http.client
import http.server
import socket
import threading
import time

from remote_servers import free_port


def kind_of(path):
    """What a request touches, from its key: lease, checkpoint, record, shard, job, a listing,
    a (bulk) delete, other."""
    key, _, query = path.partition("?")
    if "delete" in query:
        return "delete"
    if key.endswith(".lease"):
        return "lease"
    if key.endswith(".journal"):
        return "checkpoint"
    if key.endswith(".complete.json"):
        return "record"
    if key.endswith(".parquet") or "uploadId=" in path or "uploads" in path.split("?")[-1]:
        return "shard"
    if key.endswith(("job.json", "manifest.jsonl")) or "/manifest/" in key:
        return "job"
    return "list" if "list-type" in path or "prefix=" in path else "other"


class Handler(http.server.BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"

    def log_message(self, *args):
        pass

    def _forward(self):
        proxy = self.server.proxy
        length = int(self.headers.get("Content-Length") or 0)
        fault = proxy.take_fault(self.command, self.path)
        if fault and fault[0] == "down":
            proxy.go_down(fault[1])
        if proxy.is_down():
            self.close_connection = True
            self.connection.shutdown(socket.SHUT_RDWR)
            return
        if fault and fault[0] == "delay":
            time.sleep(fault[1])
        if fault and fault[0] == "cut":
            self.rfile.read(length // 2)
            self.close_connection = True
            self.connection.shutdown(2)
            return
        body = self.rfile.read(length) if length else None
        proxy.count(self.command, self.path, length)
        if fault and fault[0] == "status":
            payload = (b"<?xml version=\"1.0\"?><Error><Code>SlowDown</Code>"
                       b"<Message>Please reduce your request rate.</Message></Error>")
            self.send_response(fault[1])
            self.send_header("Content-Type", "application/xml")
            self.send_header("Content-Length", str(len(payload)))
            self.end_headers()
            self.wfile.write(payload)
            return
        conn = http.client.HTTPConnection("127.0.0.1", proxy.upstream_port, timeout=60)
        headers = {k: v for k, v in self.headers.items() if k.lower() != "connection"}
        conn.request(self.command, self.path, body=body, headers=headers)
        r = conn.getresponse()
        data = r.read()
        proxy.count_down(self.command, self.path, len(data))
        self.send_response(r.status)
        for k, v in r.getheaders():
            if k.lower() not in ("transfer-encoding", "connection", "content-length"):
                self.send_header(k, v)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(data)
        conn.close()

    do_GET = do_PUT = do_POST = do_DELETE = do_HEAD = _forward


class S3Proxy:
    """Listens on a free loopback port and forwards to `upstream_port`; `env` is the
    endpoint for sparc3d. `faults` holds rules (method, key substring, action, times, skip):
    action ("status", code), ("cut",), ("delay", seconds) or ("down", seconds), taken by the
    matching requests after the first `skip`. `refused` counts the requests closed unanswered
    while down."""

    def __init__(self, upstream_port):
        self.upstream_port = upstream_port
        self.lock = threading.Lock()
        self.counts = {}
        self.bytes_up = 0
        self.bytes_down = 0
        self.faults = []
        self.down_until = 0.0
        self.refused = 0
        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", free_port()), Handler)
        self.server.daemon_threads = True
        self.server.proxy = self
        self.endpoint = "http://127.0.0.1:%d" % self.server.server_address[1]
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def count(self, method, path, sent=0):
        with self.lock:
            key = (method, kind_of(path))
            self.counts[key] = self.counts.get(key, 0) + 1
            self.bytes_up += sent

    def count_down(self, method, path, received):
        """Bytes of a response's body (`bytes_down`; `bytes_up` counts requests' bodies)."""
        with self.lock:
            self.bytes_down += received

    def add_fault(self, method, key_part, action, times, skip=0):
        with self.lock:
            self.faults.append([method, key_part, action, times, skip])

    def take_fault(self, method, path):
        with self.lock:
            for rule in self.faults:
                if rule[0] == method and rule[1] in path and rule[3] > 0:
                    if rule[4] > 0:
                        rule[4] -= 1
                        continue
                    rule[3] -= 1
                    return rule[2]
        return None

    def go_down(self, seconds):
        with self.lock:
            self.down_until = time.time() + seconds

    def is_down(self):
        with self.lock:
            down = time.time() < self.down_until
            self.refused += down
            return down

    def reset(self):
        with self.lock:
            self.counts, self.faults = {}, []
            self.bytes_up = self.bytes_down = 0
            self.down_until, self.refused = 0.0, 0

    def close(self):
        self.server.shutdown()
