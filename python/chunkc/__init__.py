"""chunkc: a compiler for robot-learning datasets.

The wheel holds one program, the `chunkc` binary, installed beside the interpreter's own
scripts; this package only finds it (`chunkc.find_binary()`) and runs it (`python -m chunkc`).
The Python loaders that `chunkc build` writes are plain files in each output directory; their
dependencies come with `pip install "chunkc[loader]"`.
"""

from __future__ import annotations

import os
import sys
import sysconfig

__all__ = ["find_binary"]


def find_binary() -> str:
    """The path of the installed `chunkc` binary.

    Looks where pip puts a wheel's scripts for this interpreter: the environment's scripts
    directory, the user scheme's (`pip install --user`), and the `bin` next to a `--target` or
    `--prefix` install. Raises FileNotFoundError, naming the places looked at, when none has it.
    """
    exe = "chunkc" + (sysconfig.get_config_var("EXE") or "")
    places = []
    scripts = sysconfig.get_path("scripts")
    if scripts:
        places.append(scripts)
    if sys.version_info >= (3, 10):
        user_scheme = sysconfig.get_preferred_scheme("user")
    elif os.name == "nt":
        user_scheme = "nt_user"
    elif sys.platform == "darwin" and sys._framework:  # type: ignore[attr-defined]
        user_scheme = "osx_framework_user"
    else:
        user_scheme = "posix_user"
    user_scripts = sysconfig.get_path("scripts", scheme=user_scheme)
    if user_scripts:
        places.append(user_scripts)
    # pip install --target DIR puts the package in DIR and the scripts in DIR/bin; --prefix
    # puts them in PREFIX/bin with the package in PREFIX/lib/pythonX.Y/site-packages.
    here = os.path.dirname(os.path.abspath(__file__))
    places.append(os.path.join(os.path.dirname(here), "bin"))
    places.append(os.path.normpath(os.path.join(here, "..", "..", "..", "..", "bin")))
    for place in places:
        path = os.path.join(place, exe)
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return path
    raise FileNotFoundError(f"the chunkc binary is in none of: {', '.join(places)}")
