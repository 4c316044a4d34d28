"""libLLVM discovery: version parsing, selection of the newest >= 19, clear errors."""

import pytest

from veriloc_rt import backend


@pytest.mark.parametrize("name, major", [
    ("libLLVM-19.so", 19), ("libLLVM.so.19.1", 19), ("libLLVM-15.so.1", 15),
    ("libLLVM-14.0.6.so.1", 14), ("libLLVM.20.dylib", 20), ("libfoo.so", None),
])
def test_llvm_major(name, major):
    assert backend.llvm_major(name) == major


def test_find_picks_newest_at_least_19(tmp_path):
    for n in ("libLLVM-14.so", "libLLVM-15.so.1", "libLLVM-19.so", "libLLVM-20.so"):
        (tmp_path / n).write_bytes(b"")
    assert backend.find_libllvm((str(tmp_path),)).endswith("libLLVM-20.so")


def test_find_returns_none_with_only_old_llvm(tmp_path):
    for n in ("libLLVM-14.so", "libLLVM-16.so"):
        (tmp_path / n).write_bytes(b"")
    assert backend.find_libllvm((str(tmp_path),)) is None


def test_missing_llvm_names_the_package(tmp_path, monkeypatch):
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.setattr(backend, "SEARCH_DIRS", (str(tmp_path),))
    monkeypatch.setattr(backend, "find_libllvm", lambda dirs=(str(tmp_path),): None)
    with pytest.raises(backend.BackendError, match="apt-get install libllvm19"):
        backend.configure_llvm()


def test_env_path_to_old_llvm_is_refused(tmp_path, monkeypatch):
    old = tmp_path / "libLLVM-15.so"
    old.write_bytes(b"")
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(old))
    with pytest.raises(backend.BackendError, match="LLVM 15"):
        backend.configure_llvm()


def test_env_path_must_exist(tmp_path, monkeypatch):
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(tmp_path / "nothing.so"))
    with pytest.raises(backend.BackendError, match="does not exist"):
        backend.configure_llvm()
