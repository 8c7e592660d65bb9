"""The index of stored results: every case reduced to its scalars and θ-grid quantities.

:func:`workflows.open_results` answers from here instead of opening every case file
(about 30 ms a case). The case files stay the truth; the index is a cache of
:func:`workflows.combine.reduce_case` of each of them, checked against them on
every read.

Files (under ``<root>/index/``)::

    results.nc             the index: a row table in the root group (``case_id``, the
                           case file's key, block and position of its row, ``case_spec``,
                           ``software_version``) and one group ``schema<k>`` per set of
                           variables (names, dims, dtypes, attributes): the reduced
                           cases of that set stacked along ``case``
    pending/<id>.entry     a case's reduced values, written by the worker that stored it
                           (a JSON header and the raw arrays: 0.3 ms to read, where a
                           small netCDF file costs 10-50 ms)
    schemas/<hash>.nc      one reduced case per set of variables: the names, dims, dtypes
                           and attributes the pending entries of that set are read with
    lock                   held (``fcntl.flock``) while ``results.nc`` is rewritten

How it stays true
-----------------
A row is used only while its recorded key (inode, size, mtime, ctime of the case file,
:func:`workflows.store_files.file_key`) equals the key of the file in ``cases/`` now, so a
case forced again (a new file) or removed is never answered from an old row. Writers
never touch ``results.nc``: each stored case writes its own pending entry (atomically,
carrying the key of the file it describes), so concurrent workers cannot lose each
other's entries and need no lock. A reader takes a case from the index, else from its
pending entry, else from the case file itself (logged as a warning: the index was
missing, stale or corrupt). When it had to read case files, or the index is unreadable,
or many entries are pending or outdated, it rewrites ``results.nc`` under the lock
(re-reading it first) and deletes the pending entries now covered. The index file is
read through one open handle, so a concurrent rewrite (``os.replace``) cannot mix two
versions.
"""
from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import logging
import math
import os
import struct
import zlib
from collections import defaultdict
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import dask
import numpy as np
import xarray as xr
from xarray.backends.netCDF4_ import NETCDF4_PYTHON_LOCK

from .bounded import BoundedMemo
from .combine import label_cases, read_reduced, reduce_case, stack_cases
from .files import unverifiable, verify, write_atomically
from .store_files import (OPEN_OPTIONS, FileKey, StoreFiles, check_case_id, data_variables, file_key,
                          netcdf_encoding, netcdf_lock)

logger = logging.getLogger(__name__)

INDEX_FORMAT = 1
#: Pending (or outdated) entries tolerated before a read rewrites the index file: at
#: least :data:`PENDING_MIN`, or one per :data:`PENDING_FRACTION` indexed cases.
PENDING_MIN = 64
PENDING_FRACTION = 16
_ENTRY_MAGIC = b"TCIDX1\n"
_DECODE = {k: v for k, v in OPEN_OPTIONS.items() if k != "engine"}
_NO_KEY: FileKey = (-1, -1, -1, -1)


@dataclass
class _Row:
    block: int
    position: int
    key: FileKey
    spec: str
    version: str


@dataclass
class _Table:
    """Reduced cases: blocks (stacked along ``case``) and where each case's row is."""

    blocks: list[xr.Dataset] = field(default_factory=list)
    rows: dict[str, _Row] = field(default_factory=dict)
    broken: bool = False

    def key(self, case_id: str) -> FileKey:
        row = self.rows.get(case_id)
        return _NO_KEY if row is None else row.key

    def add(self, block: xr.Dataset, ids: Sequence[str], meta: dict[str, tuple[FileKey, str, str]]) -> None:
        """Append a block whose rows are the cases ``ids``; ``meta``: id -> (key, spec, version)."""
        b = len(self.blocks)
        self.blocks.append(block)
        for position, case_id in enumerate(ids):
            self.rows[case_id] = _Row(b, position, *meta[case_id])

    def select(self, ids: Sequence[str]) -> list[tuple[list[str], xr.Dataset]]:
        """``(ids, rows of those cases in memory)`` per block, for cases of ``ids`` held here."""
        by_block: dict[int, list[str]] = defaultdict(list)
        for case_id in ids:
            if case_id in self.rows:
                by_block[self.rows[case_id].block].append(case_id)
        return [(members, _select(self.blocks[b], [self.rows[c].position for c in members]))
                for b, members in by_block.items()]


class ResultIndex:
    """The index of the files of a store (:class:`~workflows.store_files.StoreFiles`; see the
    module docstring)."""

    def __init__(self, store: StoreFiles):
        self.store = store
        self.path = store.index_dir / "results.nc"
        self.pending_dir = store.index_dir / "pending"
        self.schemas_dir = store.index_dir / "schemas"

    def pending_path(self, case_id: str) -> Path:
        """Where the pending entry of ``case_id`` is written."""
        return self.pending_dir / f"{check_case_id(case_id)}.entry"

    # -- writers ---------------------------------------------------------------------

    def add(self, ds: xr.Dataset, key: FileKey) -> None:
        """Record the case ``ds``, just stored as the case file with ``key``.

        Best effort: a failure is logged and costs a later reader one read of the
        case file, never a wrong answer.
        """
        try:
            reduced = reduce_case(ds)
            schema = hashlib.sha256(repr(_schema(reduced)).encode()).hexdigest()[:16]
            template = self.schemas_dir / f"{schema}.nc"
            if not template.is_file():
                plain = reduced.copy()
                plain.attrs = {}
                with netcdf_lock:
                    write_atomically(template, lambda tmp: _to_netcdf(plain, tmp))
                self.store.publish(template)
            header = {"case_id": reduced.attrs["case_id"], "case_spec": reduced.attrs["case_spec"],
                      "software_version": reduced.attrs.get("software_version", ""),
                      "file_key": list(key), "schema": schema}
            arrays = {n: v.values for n, v in data_variables(reduced)}
            # not fsynced: an entry damaged by a crash fails its checksum and the case file is read
            write_atomically(self.pending_path(header["case_id"]),
                             lambda tmp: tmp.write_bytes(_pack_entry(header, arrays)), durable=False)
            self.store.publish(self.pending_path(header["case_id"]), remember=False)  # its writer never reads it
        except Exception:
            logger.warning("could not write the index entry of case %s", ds.attrs.get("case_id"),
                           exc_info=True)

    def discard(self, case_id: str) -> None:
        """Forget the pending entry of a removed case (its row goes at the next rewrite)."""
        self.pending_path(case_id).unlink(missing_ok=True)
        if self.store.url:
            self.store.remote.remove(self.pending_path(case_id))

    def _sync(self) -> None:
        """A store on object storage: the cached index made the objects' (changed ones fetched)."""
        if self.store.url:
            self.store.remote.sync_folder(self.store.index_dir)

    # -- readers ---------------------------------------------------------------------

    def open_results(self, case_ids: Sequence[str] | None = None) -> xr.Dataset:
        """:func:`workflows.open_results` from the index; identical to
        :func:`workflows.combine.combine_files`."""
        with netcdf_lock:
            return self._open_results(case_ids)

    def update(self) -> int:
        """Rewrite the index file to hold every stored case now; return how many it holds."""
        with netcdf_lock:
            self._sync()
            keys = self.store.file_keys()
            with self._opened() as index:
                extra, _ = self._entries(index, sorted(keys), keys)
            return len(self._rewrite(keys, extra).rows)

    def _open_results(self, case_ids: Sequence[str] | None) -> xr.Dataset:
        self._sync()
        keys = self.store.file_keys()
        ids = list(dict.fromkeys(check_case_id(c) for c in case_ids)) if case_ids is not None \
            else sorted(keys)
        if not ids:
            raise ValueError(f"no cases to combine in {self.store.root}")
        for case_id in ids:
            if case_id not in keys:
                raise FileNotFoundError(errno.ENOENT, "case is not stored", str(self.store.case_path(case_id)))
        with self._opened() as index:
            extra, from_files = self._entries(index, ids, keys)
            pending = len(os.listdir(self.pending_dir)) if self.pending_dir.is_dir() else 0
            outdated = sum(row.key != keys.get(c) for c, row in index.rows.items())
            limit = max(PENDING_MIN, len(index.rows) // PENDING_FRACTION)
            if index.broken or from_files or pending > limit or outdated > limit:
                index, extra = self._rewrite(keys, extra), _Table()
            return _assemble(ids, [extra, index])

    def unverified(self, case_ids: Sequence[str]) -> list[str]:
        """The stored cases of ``case_ids`` whose file neither the index nor a pending entry
        describes as it is now (its key differs: written by something else, truncated,
        replaced). Their files have not been read since; the others were read whole when
        their entry was made."""
        self._sync()
        keys = self.store.file_keys()
        stored = [c for c in case_ids if c in keys]
        with netcdf_lock, self._opened() as index:
            wanted = [c for c in stored if index.key(c) != keys[c]]
        out = []
        for case_id in wanted:
            try:
                header, _ = _unpack_entry(self.pending_path(case_id).read_bytes())
            except Exception:  # none, or corrupt
                out.append(case_id)
                continue
            if tuple(header["file_key"]) != keys[case_id] or header["case_id"] != case_id:
                out.append(case_id)
        return out

    # -- internals -------------------------------------------------------------------

    def _entries(self, index: _Table, ids: Sequence[str], keys: dict[str, FileKey]) -> tuple[_Table, int]:
        """The cases of ``ids`` that ``index`` lacks or has outdated, from their pending
        entries, else from their case files; and how many came from case files."""
        wanted = [c for c in ids if index.key(c) != keys[c]]
        table = self._read_pending(wanted, keys)
        missing = [c for c in wanted if c not in table.rows]
        if missing:
            logger.warning("the index of %s lacked %d of the cases asked for (missing, stale or "
                           "corrupt); reading them from their case files and rebuilding it",
                           self.store.root, len(missing))
            reduced = {}
            for case_id in missing:
                key = keys[case_id]
                reduced[case_id] = read_reduced(self.store, case_id)
                reduced[case_id].attrs["file_key"] = key
            _add_reduced(table, reduced)
        return table, len(missing)

    def _read_pending(self, ids: Sequence[str], keys: dict[str, FileKey]) -> _Table:
        """Pending entries of ``ids`` that describe the case files with ``keys``, as blocks."""
        groups: dict[str, list[tuple[dict, dict]]] = defaultdict(list)
        for case_id in ids:
            try:
                header, arrays = _unpack_entry(self.pending_path(case_id).read_bytes())
            except FileNotFoundError:
                continue
            except Exception as exc:  # a corrupt entry: the case file still has the truth
                logger.warning("index entry of case %s is unreadable (%s); ignoring it", case_id, exc)
                continue
            if tuple(header["file_key"]) == keys.get(case_id) and header["case_id"] == case_id:
                groups[header["schema"]].append((header, arrays))
        table = _Table()
        for schema, entries in groups.items():
            try:
                block = _stack_entries(_template(self.schemas_dir / f"{schema}.nc"), [a for _, a in entries])
            except Exception as exc:
                logger.warning("index entries of schema %s are unreadable (%s); ignoring them", schema, exc)
                continue
            table.add(block, [h["case_id"] for h, _ in entries],
                      {h["case_id"]: (tuple(h["file_key"]), h["case_spec"], h["software_version"])
                       for h, _ in entries})
        return table

    @contextmanager
    def _opened(self) -> Iterator[_Table]:
        """The index file as a table whose blocks are read on demand through one open handle."""
        import netCDF4

        if not self.path.is_file():
            yield _Table()
            return
        try:
            # a damaged index, or one whose checksum is gone, is rebuilt from the case files, never read
            verify(self.path, without_checksum=unverifiable)
            with NETCDF4_PYTHON_LOCK:  # HDF5 is not thread-safe; xarray's reads take this lock too
                nc = netCDF4.Dataset(self.path, "r")
        except Exception as exc:
            logger.warning("index %s is unreadable (%s); rebuilding it", self.path, exc)
            yield _Table(broken=True)
            return
        try:
            try:
                table = _read_table(nc)
            except Exception as exc:
                logger.warning("index %s is unreadable (%s); rebuilding it", self.path, exc)
                table = _Table(broken=True)
            yield table
        finally:
            with NETCDF4_PYTHON_LOCK:
                nc.close()

    def _rewrite(self, keys: dict[str, FileKey], extra: _Table) -> _Table:
        """Write a new index file of the rows still true, every pending entry and ``extra``; return it."""
        with self._locked(), self._opened() as old:  # re-read: another reader may have rewritten it
            pending = sorted(self.pending_dir.glob("*.entry")) if self.pending_dir.is_dir() else []
            stats = {p: _stat(p) for p in pending}
            fresh = self._read_pending([p.stem for p in pending if p.stem not in extra.rows
                                        and old.key(p.stem) != keys.get(p.stem)], keys)
            kept = [c for c, row in old.rows.items()
                    if row.key == keys.get(c) and c not in extra.rows and c not in fresh.rows]
            parts: dict[tuple, list[tuple[list[str], xr.Dataset]]] = defaultdict(list)
            meta: dict[str, tuple[FileKey, str, str]] = {}
            for table, members in ((old, kept), (extra, list(extra.rows)), (fresh, list(fresh.rows))):
                for ids, block in table.select(members):
                    parts[_schema(block)].append((ids, block))
                meta.update({c: (table.rows[c].key, table.rows[c].spec, table.rows[c].version) for c in members})
            new = _Table()
            for group in parts.values():
                block = group[0][1] if len(group) == 1 else stack_cases([b for _, b in group])
                block.attrs = {}
                new.add(block, [c for ids, _ in group for c in ids], meta)
            try:
                write_atomically(self.path, lambda tmp: _write_table(tmp, new), checksum=True)
                self.store.publish(self.path)
            except OSError as exc:  # e.g. a read-only results folder: answer anyway
                logger.warning("could not write the index %s: %s", self.path, exc)
                return new
            covered = []
            for path, stat in stats.items():  # covered now, a removed case, or an older file's entry
                key = keys.get(path.stem)
                if stat is not None and (path.stem in new.rows or key is None or stat[1] < key[2]) \
                        and _stat(path) == stat:
                    path.unlink(missing_ok=True)
                    covered.append(path)
            if self.store.url:  # a rewrite elsewhere that missed these falls back to the case files
                self.store.remote.remove(*covered)
        logger.info("index of %s rewritten: %d cases", self.store.root, len(new.rows))
        return new

    @contextmanager
    def _locked(self) -> Iterator[None]:
        self.store.index_dir.mkdir(parents=True, exist_ok=True)
        with open(self.store.index_dir / "lock", "a+") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)


def _assemble(ids: Sequence[str], tables: Sequence[_Table]) -> xr.Dataset:
    """Combined results of ``ids``, each taken from the first of ``tables`` that holds it."""
    parts, order, rows = [], [], {}
    for table in tables:
        members = [c for c in ids if c in table.rows and c not in rows]
        rows.update({c: table.rows[c] for c in members})
        for block_ids, block in table.select(members):
            parts.append(block)
            order += block_ids
    stacked = parts[0] if len(parts) == 1 else stack_cases(parts)
    if order != list(ids):
        where = {c: i for i, c in enumerate(order)}
        stacked = stacked.isel(case=[where[c] for c in ids])
    stacked.attrs = {}
    return label_cases(stacked, ids, [rows[c].spec for c in ids], rows[ids[0]].version)


def _add_reduced(table: _Table, reduced: dict[str, xr.Dataset]) -> None:
    """Add reduced cases (from case files) to ``table``, one block per schema."""
    groups: dict[tuple, list[str]] = defaultdict(list)
    for case_id, ds in reduced.items():
        groups[_schema(ds)].append(case_id)
    for ids in groups.values():
        meta = {c: (tuple(reduced[c].attrs["file_key"]), reduced[c].attrs["case_spec"],
                    reduced[c].attrs.get("software_version", "")) for c in ids}
        table.add(stack_cases([reduced[c] for c in ids]), ids, meta)


def _schema(ds: xr.Dataset) -> tuple:
    """What must agree for reduced cases to share a block: names, dims, dtypes, attributes."""
    return tuple(sorted((str(n), tuple(d for d in v.dims if d != "case"), v.dtype.str,
                         repr(sorted(v.attrs.items()))) for n, v in ds.variables.items()))


def _select(block: xr.Dataset, positions: list[int]) -> xr.Dataset:
    """Rows ``positions`` of a block, in memory (whole reads when most rows are wanted)."""
    n = block.sizes["case"]
    if positions == list(range(n)):
        return block.load()
    if len(positions) * 8 > n:
        return block.load().isel(case=positions)
    return block.isel(case=positions).load()


def _stack_entries(template: xr.Dataset, entries: list[dict[str, np.ndarray]]) -> xr.Dataset:
    """Pending entries of one schema as a block: the template's variables, stacked values."""
    data = {}
    for name, var in template.data_vars.items():
        dtype = var.dtype
        data[name] = (("case", *var.dims), np.stack([np.asarray(e[name], dtype=dtype) for e in entries]),
                      dict(var.attrs))
    coords = {name: (c.dims, c.values, dict(c.attrs)) for name, c in template.coords.items()}
    return xr.Dataset(data, coords=coords)


#: Schema files read (path and version -> its dataset): a few, the most recent kept.
_TEMPLATES: BoundedMemo[tuple[str, FileKey], xr.Dataset] = BoundedMemo(8)


def _template(path: Path) -> xr.Dataset:
    """The schema file at ``path``, read once per process and version of the file."""
    key = (str(path), file_key(path.stat()))
    template = _TEMPLATES.get(key)
    if template is None:
        with netcdf_lock, xr.open_dataset(path, **OPEN_OPTIONS) as ds:
            template = _TEMPLATES[key] = ds.load()
    return template


def _stat(path: Path) -> tuple[int, int] | None:
    """(inode, mtime ns) of ``path``, or None if it is gone."""
    try:
        s = path.stat()
    except FileNotFoundError:
        return None
    return (s.st_ino, s.st_mtime_ns)


def _pack_entry(header: dict, arrays: dict[str, np.ndarray]) -> bytes:
    """``_ENTRY_MAGIC``, header length (8 bytes), JSON header (with the arrays' CRC-32), the raw arrays."""
    variables, chunks, offset = [], [], 0
    for name, values in arrays.items():
        values = np.asarray(values, order="C")  # (ascontiguousarray would make 0-d arrays 1-d)
        if values.dtype.hasobject:
            raise TypeError(f"{name}: object arrays are not stored in index entries")
        variables.append([name, values.dtype.str, list(values.shape), offset])
        chunks.append(values.tobytes())
        offset += len(chunks[-1])
    payload = b"".join(chunks)
    text = json.dumps({**header, "variables": variables, "crc32": zlib.crc32(payload)}).encode()
    return _ENTRY_MAGIC + struct.pack("<Q", len(text)) + text + payload


def _unpack_entry(buffer: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """Inverse of :func:`_pack_entry`."""
    if not buffer.startswith(_ENTRY_MAGIC):
        raise ValueError("not an index entry")
    start = len(_ENTRY_MAGIC) + 8
    (length,) = struct.unpack("<Q", buffer[len(_ENTRY_MAGIC):start])
    header = json.loads(buffer[start:start + length])
    base = start + length
    if zlib.crc32(buffer[base:]) != header["crc32"]:
        raise ValueError("index entry fails its checksum")
    arrays = {}
    for name, dtype, shape, offset in header["variables"]:
        dtype = np.dtype(dtype)
        count = math.prod(shape)
        if base + offset + count * dtype.itemsize > len(buffer):
            raise ValueError("index entry is truncated")
        arrays[name] = np.frombuffer(buffer, dtype=dtype, count=count, offset=base + offset).reshape(shape)
    return header, arrays


def _read_table(nc) -> _Table:
    """Rows and (lazy) blocks of an open index file."""
    with NETCDF4_PYTHON_LOCK:
        version, n_blocks = int(nc.getncattr("index_format")), int(nc.getncattr("blocks"))
        groups = [nc.groups[f"schema{b}"] for b in range(n_blocks)]
    if version != INDEX_FORMAT:
        raise ValueError(f"index format {version} is not {INDEX_FORMAT}")
    rows = xr.open_dataset(xr.backends.NetCDF4DataStore(nc), **_DECODE).load()
    table = _Table(blocks=[xr.open_dataset(xr.backends.NetCDF4DataStore(g), **_DECODE) for g in groups])
    block, position, key = rows["block"].values, rows["position"].values, rows["file_key"].values
    specs, versions = rows["case_spec"].values, rows["software_version"].values
    for i, case_id in enumerate(rows["case_id"].values):
        b, p = int(block[i]), int(position[i])
        if not (0 <= b < len(table.blocks) and 0 <= p < table.blocks[b].sizes["case"]):
            raise ValueError("a row points outside its block")
        table.rows[str(case_id)] = _Row(b, p, tuple(int(k) for k in key[i]), str(specs[i]), str(versions[i]))
    return table


def _write_table(path: Path, table: _Table) -> None:
    ids = list(table.rows)
    rows = [table.rows[c] for c in ids]
    index = xr.Dataset(
        {"case_id": ("row", np.asarray(ids, dtype=object)),
         "block": ("row", np.asarray([r.block for r in rows], dtype=np.int32)),
         "position": ("row", np.asarray([r.position for r in rows], dtype=np.int32)),
         "file_key": (("row", "key"), np.asarray([r.key for r in rows], dtype=np.int64).reshape(-1, 4)),
         "case_spec": ("row", np.asarray([r.spec for r in rows], dtype=object)),
         "software_version": ("row", np.asarray([r.version for r in rows], dtype=object))},
        attrs={"index_format": INDEX_FORMAT, "blocks": len(table.blocks),
               "title": "tunnel-contact index of stored results (a cache of the case files)"})
    _to_netcdf(index, path)
    for b, block in enumerate(table.blocks):
        _to_netcdf(block, path, group=f"schema{b}")


def _to_netcdf(ds: xr.Dataset, path: Path, group: str | None = None) -> None:
    # synchronous: no distributed write lock when called inside a dask worker
    with dask.config.set(scheduler="synchronous"):
        ds.to_netcdf(path, mode="a" if group else "w", group=group, engine="netcdf4",
                     encoding=netcdf_encoding(ds, compress=False))
