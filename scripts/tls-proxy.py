#!/usr/bin/env python3
"""A TLS-terminating TCP proxy: the Kafka TLS test puts it in front of the test broker
(which speaks only plaintext) and has the broker advertise the proxy's address, so that
every connection a client makes goes through TLS, as to a managed Kafka service.

    scripts/tls-proxy.py --listen 127.0.0.1:9093 --to 127.0.0.1:9092 \
        --cert server.pem --key server.key [--client-ca ca.pem]

With --client-ca, clients must present a certificate signed by it (mutual TLS, as
Aiven and MSK's TLS authentication ask). Prints "listening" once it accepts
connections, and one line for each handshake it refuses.
"""

import argparse
import socket
import ssl
import threading


def address(text):
    host, port = text.rsplit(":", 1)
    return host, int(port)


def pump(src, dst):
    try:
        while True:
            data = src.recv(65536)
            if not data:
                break
            dst.sendall(data)
    except OSError:
        pass
    finally:
        for s in (src, dst):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass


def serve(context, conn, upstream):
    try:
        conn.settimeout(10)
        tls = context.wrap_socket(conn, server_side=True)
        tls.settimeout(None)
    except (ssl.SSLError, OSError) as e:
        print(f"handshake refused: {e}", flush=True)
        conn.close()
        return
    try:
        up = socket.create_connection(upstream, timeout=10)
        up.settimeout(None)
    except OSError as e:
        print(f"upstream {upstream}: {e}", flush=True)
        tls.close()
        return
    threading.Thread(target=pump, args=(tls, up), daemon=True).start()
    pump(up, tls)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--listen", type=address, required=True)
    ap.add_argument("--to", type=address, required=True)
    ap.add_argument("--cert", required=True)
    ap.add_argument("--key", required=True)
    ap.add_argument("--client-ca")
    args = ap.parse_args()
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    context.load_cert_chain(args.cert, args.key)
    if args.client_ca:
        context.verify_mode = ssl.CERT_REQUIRED
        context.load_verify_locations(args.client_ca)
    server = socket.create_server(args.listen)
    print("listening", flush=True)
    while True:
        conn, _ = server.accept()
        threading.Thread(target=serve, args=(context, conn, args.to), daemon=True).start()


if __name__ == "__main__":
    main()
