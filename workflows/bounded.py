"""A process's memo of what it has checked, bounded: the least recently used entries go first.

The API and the workers remember which file versions they have verified or read (so that a
second GET does not hash or open the file again). A long-running service meets every case of
its store, so an unbounded memo grows with the store (about 0.3 kB a case each); bounded, the
memo keeps the recent ones and an evicted file is simply verified again when next asked for."""
from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Generic, Hashable, Optional, TypeVar

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")


class BoundedMemo(Generic[K, V]):
    """A thread-safe mapping of at most ``size`` entries, least recently used evicted first."""

    def __init__(self, size: int):
        if size < 1:
            raise ValueError("size: at least 1")
        self.size = size
        self._items: OrderedDict[K, V] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: K, default: Optional[V] = None) -> Optional[V]:
        with self._lock:
            if key not in self._items:
                return default
            self._items.move_to_end(key)
            return self._items[key]

    def __setitem__(self, key: K, value: V) -> None:
        with self._lock:
            self._items[key] = value
            self._items.move_to_end(key)
            while len(self._items) > self.size:
                self._items.popitem(last=False)

    def __contains__(self, key: K) -> bool:
        with self._lock:
            return key in self._items

    def pop(self, key: K, default: Optional[V] = None) -> Optional[V]:
        with self._lock:
            return self._items.pop(key, default)

    def __len__(self) -> int:
        return len(self._items)

    def clear(self) -> None:
        with self._lock:
            self._items.clear()
