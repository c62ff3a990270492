"""Only what pyproject.toml cannot say: ship ``mi_npr_llvm.pth`` at the root of site-packages.

The ``.pth`` file makes ``import mitsuba`` find a usable libLLVM without ``import mi_npr`` first
(see ``mi_npr_llvm_hook.py``). A wheel carries it when ``build_py`` copies it into ``build_lib``
(``pip install .``); an editable install (``pip install -e .``) builds its own wheel without the
build directory, so ``editable_wheel`` adds the file to that wheel too.
"""

from __future__ import annotations

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

PTH = "mi_npr_llvm.pth"
HERE = Path(__file__).resolve().parent


class build_py_with_pth(build_py):
    def run(self) -> None:
        super().run()
        self.copy_file(str(HERE / PTH), str(Path(self.build_lib, PTH)), preserve_mode=0)

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        return [*super().get_outputs(include_bytecode), str(Path(self.build_lib, PTH))]


cmdclass: dict[str, type] = {"build_py": build_py_with_pth}

try:
    from setuptools.command.editable_wheel import editable_wheel
except ImportError:  # setuptools < 64: no PEP 660 editable wheels
    pass
else:

    class editable_wheel_with_pth(editable_wheel):
        def _create_wheel_file(self, bdist_wheel):  # type: ignore[no-untyped-def]
            from zipfile import ZIP_DEFLATED, ZipFile

            wheel_path = super()._create_wheel_file(bdist_wheel)
            # The RECORD is rewritten by pip from what it installs; an extra root file is fine.
            with ZipFile(wheel_path, "a", compression=ZIP_DEFLATED) as whl:
                if PTH not in whl.namelist():
                    whl.write(HERE / PTH, PTH)
            return wheel_path

    cmdclass["editable_wheel"] = editable_wheel_with_pth

setup(cmdclass=cmdclass)
