"""Two Python threads sleeping at 100 Hz and 20 Hz for 1 s, handing their ticks to the main thread
through a queue (CPython's GIL and queue are pthread mutexes and condition variables with deadlines);
prints the ticks, how many the main thread got and the elapsed monotonic time."""
import json
import queue
import threading
import time

q: queue.Queue[str] = queue.Queue()
ticks = {"fast": 0, "slow": 0}


def worker(name: str, period: float) -> None:
    for _ in range(round(1.0 / period)):
        time.sleep(period)
        ticks[name] += 1
        q.put(name)


t0 = time.monotonic()
periods = {"fast": 0.01, "slow": 0.05}
threads = [threading.Thread(target=worker, args=item) for item in periods.items()]
for t in threads:
    t.start()
got = 0
while got < 120:
    try:
        q.get(timeout=0.5)
        got += 1
    except queue.Empty:
        break
for t in threads:
    t.join()
print(json.dumps({"ticks": ticks, "got": got, "elapsed_ns": time.monotonic_ns() - int(t0 * 1e9)}))
