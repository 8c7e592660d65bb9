"""A result store on object storage: ``TUNNEL_CONTACT_RESULTS=s3://bucket/prefix`` (any fsspec URL
but a local path).

The objects keep the layout of the local folder (:mod:`workflows.store_files`) under the URL's
prefix. Each process works in a local cache folder of its own (:func:`cache_folder`): a file is
written there as before (atomically, with its checksum), then *published*: uploaded as one
object, its checksum as a ``.b2`` object first, or, for a case file, in the object's metadata
(``x-amz-meta-blake2b``: one request; a ``.b2`` object where the store has no metadata or the file
is larger than :data:`SINGLE_PUT`). S3 shows an object only once its upload is complete, so no
reader ever sees a part of one. A case file is read from the cache once its copy matches the
object's current ETag and its bytes the object's checksum (:meth:`Remote.fetch`): a damaged object
is never served. The workers write to the bucket directly; nothing needs a shared disk.

Endpoint and keys: the standard ``AWS_*`` variables (``AWS_ENDPOINT_URL`` for an S3-compatible
server, ``AWS_ACCESS_KEY_ID``, ``AWS_SECRET_ACCESS_KEY``), or ``TUNNEL_CONTACT_STORAGE_OPTIONS``, a
JSON object of fsspec options (``{"endpoint_url": ..., "key": ..., "secret": ...}``). Every process
(API, workers) reads them from its own environment.
"""
from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from email.utils import parsedate_to_datetime
from functools import cached_property
from pathlib import Path
from typing import Any, Iterable, Optional

logger = logging.getLogger(__name__)

#: Suffix of the sidecar that records which object version (ETag) a cached file is a copy of.
ETAG_SUFFIX = ".etag"
#: The user-metadata key of an object's BLAKE2b checksum (the ``.b2`` file's text, travelling with
#: the object: written by its PutObject, read back by the HEAD that tells whether a copy is current).
CHECKSUM_METADATA = "blake2b"


def is_url(location: Any) -> bool:
    """Whether ``location`` names object storage (``s3://…``, ``gs://…``), not a local path."""
    return isinstance(location, str) and "://" in location and not location.startswith("file://")


def storage_options(protocol: str, environ: Optional[dict] = None) -> dict[str, Any]:
    """fsspec options from ``TUNNEL_CONTACT_STORAGE_OPTIONS`` (JSON), else the ``AWS_*`` variables
    botocore reads itself, with ``AWS_ENDPOINT_URL`` passed on explicitly for S3.

    On S3, unless the options set ``config_kwargs``: no SHA-256 of each upload's body for its
    signature (botocore signs bodies only over plain HTTP, a store on the local network; over
    HTTPS it never does). The body is still checked in transit by the CRC32 checksum botocore
    sends, and every file against its BLAKE2b checksum when read; hashing a 1.3 MB case file
    twice was a third of the client's time per case."""
    environ = os.environ if environ is None else environ
    options = json.loads(environ.get("TUNNEL_CONTACT_STORAGE_OPTIONS") or "{}")
    if protocol in ("s3", "s3a"):
        if environ.get("AWS_ENDPOINT_URL") and "endpoint_url" not in options \
                and "endpoint_url" not in options.get("client_kwargs", {}):
            options["endpoint_url"] = environ["AWS_ENDPOINT_URL"]
        options.setdefault("config_kwargs", {"s3": {"payload_signing_enabled": False}})
    return options


def cache_folder(url: str) -> Path:
    """This process's cache of the store at ``url``: ``$TUNNEL_CONTACT_CACHE`` if set, else a
    folder per URL under the user's cache (``~/.cache/tunnel-contact``)."""
    base = os.environ.get("TUNNEL_CONTACT_CACHE")
    if base:
        return Path(base)
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return home / "tunnel-contact" / hashlib.sha256(url.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Remote:
    """The objects under ``url``; ``cache``: the local folder the store's files are worked on in."""

    url: str
    cache: Path

    @cached_property
    def fs(self):
        import fsspec

        protocol = self.url.split("://", 1)[0]
        # no listings cache: other processes add objects all the time
        return fsspec.filesystem(protocol, use_listings_cache=False,
                                 **storage_options(protocol))

    @property
    def base(self) -> str:
        return self.url.split("://", 1)[1].rstrip("/")

    def key(self, path: Path | str) -> str:
        """The object key of the cached file ``path`` (or of a path relative to the cache)."""
        relative = Path(path).relative_to(self.cache) if Path(path).is_absolute() else Path(path)
        return f"{self.base}/{relative.as_posix()}"

    def make_bucket(self) -> None:
        """Create the bucket if missing (a new deployment's first start)."""
        bucket = self.base.split("/", 1)[0]
        if not self.fs.exists(bucket):
            try:
                self.fs.mkdir(bucket)
            except (FileExistsError, PermissionError, OSError) as exc:  # made meanwhile by another replica
                if not self.fs.exists(bucket):
                    raise OSError(f"cannot make the bucket {bucket}: {exc}") from exc

    # -- objects -------------------------------------------------------------------------

    def publish(self, path: Path, *, remember: bool = True, checksum_in_metadata: bool = False) -> Optional[dict]:
        """Upload the cached file ``path`` as its object, with its checksum if it has one, recording
        the ETag the copy now matches; the object's info (from the upload's answer: no HEAD, where
        the store is S3). The checksum goes as a checksum object first, which a reader syncing the
        folder by a listing gets with the file (the index), or, with ``checksum_in_metadata``, in
        the object's metadata (one request; read back by the HEAD of :meth:`fetch`: case files).
        Without ``remember`` (a file its writer never reads back, such as a worker's index entry)
        the copy is fetched again by whoever reads it."""
        checksum = path.with_name(path.name + ".b2")
        digest = checksum.read_text().strip() if checksum.is_file() else None
        info = self._upload(path, digest, checksum_in_metadata)
        if not remember:
            self._sidecar(path).unlink(missing_ok=True)
            return None
        self._remember(path, info)
        return info

    def _upload(self, path: Path, digest: Optional[str], in_metadata: bool) -> Optional[dict]:
        """One file as its object, after its checksum object (a ``digest`` not ``in_metadata``); its
        info (ETag, size). On S3 a file up to :data:`SINGLE_PUT` is one PutObject (carrying the digest
        ``in_metadata``), whose answer carries the ETag; otherwise fsspec's upload (multipart where
        large) and a HEAD, the checksum always an object."""
        key = self.key(path)
        size = path.stat().st_size
        single = hasattr(self.fs, "call_s3") and size <= SINGLE_PUT
        if digest and not (single and in_metadata):
            self.fs.pipe_file(self.key(path.with_name(path.name + ".b2")), (digest + "\n").encode())
        if single:
            bucket, _, name = key.partition("/")
            metadata = {CHECKSUM_METADATA: digest} if digest and in_metadata else {}
            answer = self.fs.call_s3("put_object", Bucket=bucket, Key=name, Body=path.read_bytes(),
                                     Metadata=metadata)
            return {"ETag": answer.get("ETag"), "size": size, "Metadata": metadata}
        self.fs.put_file(str(path), key)
        return self.info(path)

    def info(self, path: Path) -> Optional[dict]:
        """The object's size, ETag, time and metadata (one HEAD; on S3 also ``Date``, the store's
        clock when it answered), None if there is none."""
        key = self.key(path)
        try:
            if hasattr(self.fs, "call_s3"):  # s3fs's info lists the prefix after a 404 (a folder?): a HEAD alone
                bucket, _, name = key.partition("/")
                head = self.fs.call_s3("head_object", Bucket=bucket, Key=name)
                date = head.get("ResponseMetadata", {}).get("HTTPHeaders", {}).get("date")
                return {"ETag": head.get("ETag"), "size": head.get("ContentLength"),
                        "LastModified": head.get("LastModified"), "Metadata": head.get("Metadata") or {},
                        "Date": parsedate_to_datetime(date) if date else None}
            return self.fs.info(key)
        except FileNotFoundError:
            return None

    def age(self, path: Path) -> Optional[float]:
        """Seconds since the object of ``path`` was written (its :meth:`info`), None if there is
        none: on S3 by the store's own clock (the answer's ``Date`` less the object's
        ``Last-Modified``, both the server's, so no machine's clock is compared with another's;
        one-second resolution), elsewhere this machine's clock against the object's time."""
        info = self.info(path)
        if info is None:
            return None
        made = info.get("LastModified") or info.get("mtime") or info.get("created")
        if isinstance(made, datetime):
            made = (made if made.tzinfo else made.replace(tzinfo=timezone.utc)).timestamp()
        now = info.get("Date")
        try:
            return (now.timestamp() if now else time.time()) - float(made)
        except (TypeError, ValueError):  # no time this file system tells: taken as new
            return 0.0

    def fetch(self, path: Path, info: Optional[dict] = None) -> bool:
        """Make the cached ``path`` a copy of its object and its checksum (the object's metadata,
        else its checksum object), downloading only when the object changed since the copy was
        made; False (and no copy) when there is no object. The copy is verified against the
        checksum by the caller (:func:`files.verify`)."""
        info = info if info is not None else self.info(path)
        if info is None:
            path.unlink(missing_ok=True)
            return False
        if path.is_file() and self._remembered(path) == etag(info):
            return True
        checksum = path.with_name(path.name + ".b2")
        digest = (info.get("Metadata") or {}).get(CHECKSUM_METADATA)
        if digest:  # the checksum the object was written with (a checksum object beside it is older)
            data = (digest + "\n").encode()
        else:  # an object without one: its checksum object, if any (published before checksums travelled)
            try:
                data = self.fs.cat_file(self.key(checksum))
            except FileNotFoundError:
                data = None
        _write(checksum, data) if data is not None else checksum.unlink(missing_ok=True)
        _write(path, self.fs.cat_file(self.key(path)))
        self._remember(path, info)
        return True

    def forget(self, path: Path) -> None:
        """Take the cached copy of ``path`` for stale (its recorded ETag dropped): the next
        :meth:`fetch` downloads the object again."""
        self._sidecar(path).unlink(missing_ok=True)

    def read(self, path: Path) -> Optional[bytes]:
        try:
            return self.fs.cat_file(self.key(path))
        except FileNotFoundError:
            return None

    def write(self, path: Path, data: bytes) -> None:
        """One object, written whole (a small record: an error, a sweep's, a cancel request)."""
        self.fs.pipe_file(self.key(path), data)

    def exists(self, path: Path) -> bool:
        return self.info(path) is not None

    def remove(self, *paths: Path) -> None:
        """Delete the objects of ``paths`` (absent ones are no error; many go in bulk requests)."""
        if len(paths) > 1:
            try:
                self.fs.rm([self.key(p) for p in paths])
                return
            except FileNotFoundError:
                pass
        for path in paths:
            try:
                self.fs.rm_file(self.key(path))
            except FileNotFoundError:
                pass

    def listing(self, folder: Path) -> dict[str, dict]:
        """``{file name: info}`` of the objects directly in ``folder`` (one listing)."""
        try:
            entries = self.fs.ls(self.key(folder), detail=True, refresh=True)
        except FileNotFoundError:
            return {}
        return {e["name"].rsplit("/", 1)[-1]: e for e in entries if e.get("type") != "directory"}

    def fetch_many(self, paths: Iterable[Path], infos: dict[Path, dict]) -> None:
        """:meth:`fetch` the cached ``paths`` whose objects changed, in one concurrent batch."""
        stale = [p for p in paths if not (p.is_file() and self._remembered(p) == etag(infos[p]))]
        if not stale:
            return
        for path, data in zip(stale, self._cat_all([self.key(p) for p in stale])):
            if data is not None:
                _write(path, data)
                self._remember(path, infos[path])

    def _cat_all(self, keys: list[str]) -> list[Optional[bytes]]:
        """The bytes of each object of ``keys`` (None where gone), fetched concurrently (an async
        file system such as s3fs: no HEAD before each GET), else one by one."""
        if getattr(self.fs, "async_impl", False):
            from fsspec.asyn import sync

            async def each(key):
                try:
                    return await self.fs._cat_file(key)
                except FileNotFoundError:
                    return None

            async def every():
                import asyncio
                return await asyncio.gather(*(each(k) for k in keys))

            return sync(self.fs.loop, every)
        out = []
        for key in keys:
            try:
                out.append(self.fs.cat_file(key))
            except FileNotFoundError:
                out.append(None)
        return out

    def sync_folder(self, folder: Path, *, recursive: bool = True) -> None:
        """Bring the cached ``folder`` in line with its objects: changed objects downloaded,
        cached files whose object is gone removed."""
        infos: dict[Path, dict] = {}
        try:
            found = self.fs.find(self.key(folder), detail=True, withdirs=False)
        except FileNotFoundError:
            found = {}
        prefix = self.key(folder) + "/"
        for name, info in found.items():
            relative = name[len(prefix):] if name.startswith(prefix) else None
            if relative and (recursive or "/" not in relative):
                infos[folder / relative] = info
        self.fetch_many(list(infos), infos)
        if folder.is_dir():
            for path in folder.rglob("*"):
                if path.is_file() and _ETAG_DIR not in path.parts and not path.name.startswith(".") \
                        and path.name != "lock" and path not in infos:
                    path.unlink(missing_ok=True)

    # -- which object version a cached copy is ------------------------------------------------

    def _sidecar(self, path: Path) -> Path:
        return self.cache / _ETAG_DIR / path.relative_to(self.cache).with_name(path.name + ETAG_SUFFIX)

    def _remember(self, path: Path, info: Optional[dict]) -> None:
        if info is not None:
            _write(self._sidecar(path), etag(info).encode())

    def _remembered(self, path: Path) -> Optional[str]:
        try:
            return self._sidecar(path).read_text()
        except FileNotFoundError:
            return None


_ETAG_DIR = ".etags"
#: Files up to this size go to S3 in one PutObject (read whole into memory): case files,
#: checksums, index entries and records; larger ones (combined files) by fsspec's upload.
SINGLE_PUT = 64 * 2**20


class ObjectCopies:
    """What a store whose files may be objects offers (mixed into
    :class:`workflows.store_files.StoreFiles`, whose ``root`` and ``url`` it reads): ``url`` None
    is a local folder, where publishing does nothing and a file is there or not."""

    root: Path
    url: Optional[str]

    def __str__(self) -> str:
        """Where the store is, as every process names it: its URL, else its folder."""
        return self.url or str(self.root)

    def __fspath__(self) -> str:
        """The folder the files are worked on in (the cache of a store on object storage)."""
        return str(self.root)

    @property
    def remote(self) -> Optional[Remote]:
        """The objects of a store on object storage; None for a local folder."""
        return Remote(self.url, self.root) if self.url else None

    def publish(self, path: Path, *, remember: bool = True) -> None:
        """Upload a file just written in the cache folder as its object (nothing for a local store;
        ``remember``: :meth:`Remote.publish`)."""
        if self.url:
            self.remote.publish(path, remember=remember)

    def fetched(self, path: Path) -> bool:
        """Whether ``path`` is there, for a store on object storage after copying its current
        object into the cache (unchanged copies are not downloaded again)."""
        return self.remote.fetch(path) if self.url else path.is_file()


def etag(info: dict) -> str:
    """What identifies one version of an object: its ETag (else size and time)."""
    tag = info.get("ETag") or info.get("etag") or info.get("md5") or ""
    return str(tag).strip('"') or f"{info.get('size')}-{info.get('LastModified') or info.get('mtime')}"


def object_key(info: dict) -> tuple[int, int, int, int]:
    """The :data:`workflows.store_files.FileKey` of an object version: its ETag as a number and
    its size (a rewrite with other bytes changes the ETag)."""
    return (int(hashlib.blake2b(etag(info).encode(), digest_size=7).hexdigest(), 16), int(info.get("size") or 0), 0, 0)


def _write(path: Path, data: bytes) -> None:
    """Replace the cached ``path`` by ``data`` at once (a temporary renamed into place)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
