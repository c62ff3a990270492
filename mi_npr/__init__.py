"""mi-npr: non-photorealistic rendering for Mitsuba 3.

``import mi_npr`` first picks a libLLVM that Dr.Jit 1.5 can use (see :mod:`mi_npr._llvm`), then
imports Mitsuba, activates a variant if none is active (``$MI_NPR_VARIANT`` or ``llvm_ad_rgb``)
and registers mi-npr's plugins (``npr_gbuffer``, ...) for it and for every later variant.

>>> import mi_npr, tempfile
>>> gb = mi_npr.render("scenes_xml/scene1.xml", width=64, height=48, spp=1)
>>> gb.shape, gb.objects[1]
((48, 64), 'back_wall')
>>> mi_npr.io.write_exr(tempfile.mkdtemp() + "/scene1.exr", gb).name
'scene1.exr'
"""

from __future__ import annotations

from . import _llvm
from ._llvm import LLVMNotFoundError
from ._version import __version__

try:
    LLVM = _llvm.configure()  # before drjit is imported: an old LLVM aborts the process
except LLVMNotFoundError:
    if not _llvm.cli_process():
        raise
    LLVM = None  # the mi-npr command reports the problem itself, in one line

if LLVM is not None:
    from ._api import *  # noqa: F403
    from ._api import __all__ as _api_all

    __all__ = ["LLVM", "LLVMNotFoundError", "__version__", *_api_all]
