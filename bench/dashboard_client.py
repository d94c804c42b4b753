"""bench/dashboard_client.py PORT SECONDS PID: one WebSocket client of the dashboard (as a browser
would be) reading every update for SECONDS; after each update prints a line
`events E dwells D cpu C % over T s` (C: the CPU share of process PID, the dashboard, since the
client connected). bench/run's node_load_dashboard keeps the last line."""
import asyncio
import sys
import time

import tornado.ioloop
import tornado.websocket


def ticks(pid):
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])  # utime + stime, clock ticks (100 per second)


async def main(port, limit_s, pid):
    ws = None
    for _ in range(100):
        try:
            ws = await tornado.websocket.websocket_connect("ws://127.0.0.1:%d/ws" % port)
            break
        except OSError:
            time.sleep(0.1)
    if ws is None:
        print("dashboard_client: no WebSocket on port %d" % port)
        return
    events = dwells = 0
    t0, c0 = time.monotonic(), ticks(pid)
    while time.monotonic() - t0 < limit_s:
        try:
            msg = await asyncio.wait_for(ws.read_message(), limit_s - (time.monotonic() - t0))
        except asyncio.TimeoutError:
            break
        if msg is None:
            break
        events += 1
        dwells += '"type": "dwell"' in msg
        elapsed = time.monotonic() - t0
        print("events %d dwells %d cpu %.2f %% over %.1f s"
              % (events, dwells, (ticks(pid) - c0) / elapsed, elapsed), flush=True)


if __name__ == "__main__":
    port, limit_s, pid = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
    tornado.ioloop.IOLoop.current().run_sync(lambda: main(port, limit_s, pid))
