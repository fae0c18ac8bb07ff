"""The compiled extension ``decrun.core._kernels`` (Cython): the core's kernels (the complex's,
the operators' and the intrinsic Delaunay flips) as machine code that loads with the module, their
one compiled implementation (:mod:`decrun.core.extension`). Everything else is declared in
pyproject.toml. An install without Cython or a C compiler leaves the extension out (the numpy
twins do the same work, slower); ``tests/core/test_extension.py`` fails under ``CI=true`` when it
is missing."""

import sys

from setuptools import Extension, setup

try:
    from Cython.Build import cythonize
except ImportError:  # a build without Cython (outside pip's isolated build): no extension
    extensions = []
else:
    # no fused multiply-add contraction (aarch64 compilers contract by default): the twins'
    # floating-point arithmetic stays bit for bit the numpy twins'
    flags = [] if sys.platform == "win32" else ["-O2", "-ffp-contract=off"]
    extensions = cythonize(
        [Extension("decrun.core._kernels", ["decrun/core/_kernels.pyx"], extra_compile_args=flags)],
        language_level=3,
        quiet=True,
    )
    for extension in extensions:
        extension.optional = True  # a failed compile warns and installs the rest

setup(ext_modules=extensions)
