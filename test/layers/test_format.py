"""clang-format (the package's .clang-format, Debian's clang-format 14) leaves every C++ file of
the package unchanged; a file that fails is named with the command that fixes it. A self-test
feeds the same check a file written badly on purpose, so the check can fail."""
import os
import shutil
import subprocess

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FOLDERS = ("src", "include", "test", "bench", "fuzz")
CLANG_FORMAT = shutil.which("clang-format-14") or shutil.which("clang-format")


def cpp_files(root):
    for folder in FOLDERS:
        for base, _, names in os.walk(os.path.join(root, folder)):
            for name in sorted(names):
                if name.endswith((".cpp", ".h")):
                    yield os.path.join(base, name)


def unformatted(paths):
    """The files clang-format would change (style from the package's .clang-format)."""
    bad = []
    for path in paths:
        result = subprocess.run([CLANG_FORMAT, "--dry-run", "--Werror", "--style=file", path],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if result.returncode != 0:
            bad.append(path)
    return bad


def test_every_cpp_file_is_formatted():
    assert CLANG_FORMAT, "clang-format is not installed (tools/install_deps.sh installs it)"
    bad = unformatted(cpp_files(REPO))
    assert not bad, ("not formatted (fix: clang-format -i FILE):\n  " +
                     "\n  ".join(os.path.relpath(p, REPO) for p in bad))


def test_check_catches_a_badly_formatted_file(tmp_path):
    assert CLANG_FORMAT, "clang-format is not installed (tools/install_deps.sh installs it)"
    shutil.copy(os.path.join(REPO, ".clang-format"), str(tmp_path / ".clang-format"))
    path = tmp_path / "src" / "bad.cpp"
    path.parent.mkdir()
    path.write_text("int  f( int a ){return a+1;}\n")
    assert unformatted(cpp_files(str(tmp_path))) == [str(path)]
