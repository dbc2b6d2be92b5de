#!/usr/bin/env bash
# Bring this checkout to a runnable state; fast and silent when nothing changed.
#
#   a. Debian packages for the C++ core (apt-get, only the missing ones)
#   b. a shared third-party venv outside the checkout, keyed by hash(requirements.lock + the
#      interpreter's path, version and ABI),
#      so heavy dependencies are installed once per machine, not once per clone
#   c. a per-checkout .venv whose site-packages append the shared env's (via a .pth file)
#   d. the three ament_python packages installed editable into .venv
#   e. the C++ core (lit_core extension + GoogleTest binaries) built and installed into .venv
#
# Environment: LIT_FORCE_SETUP=1 redoes every step; LIT_ENV_CACHE overrides ~/.cache/lit;
# LIT_PYTHON overrides the interpreter (default python3.11); LIT_SETUP_STOP_AFTER=shared-env stops
# after step b (docker/Dockerfile builds that layer from requirements.lock and this script alone).
set -euo pipefail

ROOT="$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd -P)"
VENV="$ROOT/.venv"
STAMPS="$VENV/.lit-stamps"
FORCE="${LIT_FORCE_SETUP:-0}"
CACHE="${LIT_ENV_CACHE:-$HOME/.cache/lit}"
PACKAGES=(lit_msgs_json lit_learner lit_planner)  # dependency order

say() { printf '[lit setup] %s\n' "$*" >&2; }
die() { say "ERROR: $*"; exit 1; }
as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }
hash_stdin() { sha256sum | cut -c1-64; }
# A stamp is up to date when it holds exactly the expected hash (and no force was requested).
stamp_ok() { [ "$FORCE" != 1 ] && [ -f "$STAMPS/$1" ] && [ "$(<"$STAMPS/$1")" = "$2" ]; }
stamp_set() { mkdir -p "$STAMPS" && printf '%s\n' "$2" >"$STAMPS/$1"; }

# One setup at a time per checkout (parallel `./lit test` runs are common); a no-op holds it ~0.1 s.
mkdir -p "$CACHE"
exec {checkout_lock_fd}>"$CACHE/checkout-$(printf '%s' "$ROOT" | hash_stdin | cut -c1-16).lock"
if ! flock -n "$checkout_lock_fd"; then
  say "waiting for another setup of $ROOT"
  flock "$checkout_lock_fd"
fi

# ---------------------------------------------------------------- a. Debian packages
# OMPL's CMake config links Boost serialization/filesystem/system by their .so dev symlinks, which
# libompl-dev itself does not pull in.
DEB_PACKAGES=(g++ cmake ninja-build libompl-dev libeigen3-dev libboost-dev
              libboost-serialization-dev libboost-filesystem-dev libboost-system-dev
              libfcl-dev libgtest-dev googletest)
PYTHON="${LIT_PYTHON:-python3.11}"
if [ -n "${LIT_PYTHON:-}" ] && ! command -v "$PYTHON" >/dev/null 2>&1; then
  # It was replaced by Debian's python3.11 without a word (and a new environment built for it).
  die "LIT_PYTHON=$LIT_PYTHON is not an interpreter on this machine; set it to one, or unset it \
for python3.11"
elif ! command -v "$PYTHON" >/dev/null 2>&1; then
  # No pyenv/other 3.11 on PATH: Debian 12's own 3.11 with venv and headers does the job.
  DEB_PACKAGES+=(python3.11 python3.11-venv python3.11-dev)
  PYTHON=python3.11
elif ! "$PYTHON" -c 'import ensurepip, os, sys, sysconfig
sys.exit(not os.path.isfile(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' \
    >/dev/null 2>&1; then
  # Debian 12's python3.11 comes without venv (ensurepip) and its C headers (Python.h), which the
  # environments and the core's build need: python3.11-venv and python3.11-dev bring them.
  if [ "$(readlink -f "$(command -v "$PYTHON")")" = /usr/bin/python3.11 ]; then
    DEB_PACKAGES+=(python3.11-venv python3.11-dev)
  else
    die "$(command -v "$PYTHON") has no venv module (ensurepip) or no C headers (Python.h); \
install them for that interpreter, or set LIT_PYTHON to one that has both"
  fi
fi
missing=()
installed="$(dpkg-query -W -f='${Package} ${Status}\n' "${DEB_PACKAGES[@]}" 2>/dev/null || true)"
for pkg in "${DEB_PACKAGES[@]}"; do
  grep -qxF "$pkg install ok installed" <<<"$installed" || missing+=("$pkg")
done
if [ "${#missing[@]}" -gt 0 ]; then
  if [ "$(id -u)" -ne 0 ] && ! command -v sudo >/dev/null 2>&1; then
    # as_root would fail with "sudo: command not found", twice, and no word on what to do.
    die "set-up needs these Debian packages, and installing them needs root (no sudo here): \
run as root: apt-get install ${missing[*]}"
  fi
  say "installing Debian packages: ${missing[*]}"
  # Another apt-get (another checkout's setup, unattended upgrades) may hold dpkg's lock: wait
  # for it up to 10 minutes instead of failing at once.
  apt_install() {
    as_root env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y \
      --no-install-recommends "$@" >&2
  }
  if ! apt_install "${missing[@]}"; then
    # A sudo that refuses (not in sudoers, a password without a terminal) was blamed on the network.
    as_root true 2>/dev/null || die "installing Debian packages needs root, and sudo refused: \
run as root: apt-get install ${missing[*]}"
    say "apt-get install failed; running apt-get update and retrying once"
    as_root env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 update >&2 \
      || die "apt-get update failed (no network to the Debian mirrors, or apt's lists are locked?)"
    apt_install "${missing[@]}" || die "could not install Debian packages: ${missing[*]}"
  fi
fi

# ---------------------------------------------------------------- b. shared third-party env
LOCK="$ROOT/requirements.lock"
[ -f "$LOCK" ] || die "missing $LOCK"
PY_VERSION="$("$PYTHON" -c 'import sys; print(sys.version)')" \
  || die "$PYTHON does not run"
# The interpreter as the environment depends on it: its file, version and ABI. Not the full
# sys.version, whose build date changes with every Debian security update of python3.11 (each
# one made a new 5.8 GB environment).
PY_IDENTITY="$("$PYTHON" -c 'import os, sys, sysconfig
print(os.path.realpath(sys.executable), *sys.version_info[:2], sysconfig.get_config_var("SOABI"))')"
DEPS_KEY="$({ cat "$LOCK"; printf '%s' "$PY_IDENTITY"; } | hash_stdin | cut -c1-16)"
SHARED="$CACHE/deps-$DEPS_KEY"
# An environment made under the former key (lock + sys.version) of this same interpreter serves.
LEGACY="$CACHE/deps-$({ cat "$LOCK"; printf '%s' "$PY_VERSION"; } | hash_stdin | cut -c1-16)"
if [ ! -e "$SHARED" ] && [ -f "$LEGACY/.complete" ] && [ "$FORCE" != 1 ]; then
  ln -sfn "$(basename "$LEGACY")" "$SHARED"
fi

if [ ! -f "$SHARED/.complete" ] || [ "$FORCE" = 1 ]; then
  exec {lock_fd}>"$CACHE/deps-$DEPS_KEY.lock"
  if ! flock -n "$lock_fd"; then
    say "waiting for another checkout that is setting up $SHARED"
    flock "$lock_fd"
  fi
  # Re-check under the lock: the other setup may have finished it meanwhile.
  if [ ! -f "$SHARED/.complete" ] || [ "$FORCE" = 1 ]; then
    if [ -L "$SHARED" ]; then  # a former key's environment, forced: made anew under this key
      rm -f "$SHARED"
    elif [ -e "$SHARED" ]; then
      say "removing incomplete or forced shared environment $SHARED"
      rm -f "$SHARED/.complete"  # first: a removal cut short leaves an environment marked incomplete
      rm -rf "$SHARED"
    fi
    say "creating shared environment $SHARED (Python ${PY_VERSION%% *})"
    "$PYTHON" -m venv "$SHARED"
    say "installing requirements.lock into the shared environment"
    "$SHARED/bin/python" -m pip install --quiet --no-input -r "$LOCK" \
      || die "pip install -r requirements.lock failed (the incomplete env is rebuilt next time)"
    "$SHARED/bin/python" -m pip check >&2 \
      || die "inconsistent shared environment $SHARED (pip check, above): requirements.lock pins \
versions that do not fit together"
    # Report packages pip pulled in that the lock does not pin (the lock should be complete).
    # (.egg-info directories bundled inside the ros-* wheels are not distributions of their own.)
    unpinned="$("$SHARED/bin/python" -c 'import importlib.metadata as m
for d in m.distributions():
    if str(getattr(d, "_path", "")).endswith(".dist-info") and d.metadata["Name"] != "pip":
        print(d.metadata["Name"])' \
      | tr 'A-Z_.' 'a-z--' | sort -u \
      | comm -23 - <(grep -v '^\s*#' "$LOCK" | cut -d= -f1 | tr 'A-Z_.' 'a-z--' | sort -u))" || true
    [ -z "$unpinned" ] || say "WARNING: requirements.lock does not pin: $(echo $unpinned)"
    cp "$LOCK" "$SHARED/requirements.lock"
    touch "$SHARED/.complete"
    # Not removed here: another checkout (an older requirements.lock, another interpreter) may use
    # them. Named, with their size, so a full disk is not a mystery.
    for other in "$CACHE"/deps-*/; do
      other="${other%/}"
      [ "$(readlink -f "$other")" = "$(readlink -f "$SHARED")" ] || [ -L "$other" ] \
        || say "another shared environment: $other ($(du -sh "$other" 2>/dev/null | cut -f1));" \
               "remove it with rm -rf when no checkout uses it"
    done
  fi
  exec {lock_fd}>&-
fi
SHARED_SITE="$(echo "$SHARED"/lib/python3*/site-packages)"
[ -d "$SHARED_SITE" ] || die "no site-packages in $SHARED"
if [ "${LIT_SETUP_STOP_AFTER:-}" = shared-env ]; then
  say "stopping after the shared environment (LIT_SETUP_STOP_AFTER=shared-env)"
  exit 0
fi

# ---------------------------------------------------------------- c. per-checkout .venv
# The .venv is tied to one shared env (and so to one Python) and to where the checkout is (its
# scripts, .pth files and ctest tree hold absolute paths: a copied checkout ran and tested the
# original's code, a moved one failed at every command); either changing means a new .venv.
if ! stamp_ok env "$SHARED $VENV" || [ ! -x "$VENV/bin/python" ]; then
  [ -e "$VENV" ] && say "recreating $VENV" || say "creating $VENV"
  rm -rf "$VENV"
  # No pip of its own: pip, setuptools, pytest, ... come from the shared env, and a bundled older
  # setuptools in .venv would shadow the pinned one.
  "$PYTHON" -m venv --without-pip "$VENV"
  VENV_SITE="$(echo "$VENV"/lib/python3*/site-packages)"
  # The shared env joins .venv through a .pth file that imports _lit_shared_env (written below).
  printf 'import _lit_shared_env\n' >"$VENV_SITE/_lit_shared_env.pth"
  cat >"$VENV_SITE/_lit_shared_env.py" <<PYEOF
"""Join the shared third-party env ($SHARED) to this .venv (written by tools/bootstrap.sh).

The ROS 2 wheels' own bootstrapper re-executes Python with LD_LIBRARY_PATH pointing at the
*running* prefix's lib dirs, which for this .venv are the wrong ones. Do the same with the
shared env's lib dirs (once: the guard variable stops the wheels' bootstrapper and us), then add
the shared site-packages (addsitedir also runs its .pth files).
"""
import os
import site
import sys

_SHARED_SITE = "$SHARED_SITE"
_SHARED_LIB = "$SHARED/lib"
if not os.environ.get("_ROS_WHEELS_BOOTSTRAP_COMPLETE") and getattr(sys, "orig_argv", None):
    _dirs = [_SHARED_LIB] + sorted(
        os.path.join(_SHARED_SITE, d) for d in os.listdir(_SHARED_SITE)
        if d.startswith("ros_") and d.endswith(".libs")
    )
    _old = [p for p in os.environ.get("LD_LIBRARY_PATH", "").split(os.pathsep) if p]
    _env = dict(os.environ)
    _env["LD_LIBRARY_PATH"] = os.pathsep.join(_dirs + [p for p in _old if p not in _dirs])
    _env["_ROS_WHEELS_BOOTSTRAP_COMPLETE"] = "1"
    try:
        os.execve(sys.executable, sys.orig_argv, _env)
    except OSError as exc:
        sys.stderr.write(f"lit: could not re-execute Python with the ROS 2 libraries: {exc}\\n")
site.addsitedir(_SHARED_SITE)
PYEOF
  # Launchers for the shared env's commands (pytest, ruff, pip, ...) that run under .venv's
  # interpreter, so they see the checkout's editable packages too.
  shebang="#!$SHARED/bin/python"
  # An environment of the former key is reached through a link: its scripts name its own path.
  real_shebang="#!$(readlink -f "$SHARED")/bin/python"
  for tool in "$SHARED"/bin/*; do
    name="$(basename "$tool")"
    case "$name" in python*|activate*|Activate*) continue ;; esac
    [ -f "$tool" ] || continue  # bin/__pycache__ and the like
    [ -e "$VENV/bin/$name" ] && continue
    if [ "$(head -c "${#shebang}" "$tool" | tr -d '\0')" = "$shebang" ] \
        || [ "$(head -c "${#real_shebang}" "$tool" | tr -d '\0')" = "$real_shebang" ]; then
      sed "1s|^#!.*|#!$VENV/bin/python|" "$tool" >"$VENV/bin/$name"
      chmod +x "$VENV/bin/$name"
    else
      ln -s "$tool" "$VENV/bin/$name"
    fi
  done
  "$VENV/bin/python" -c 'import numpy, pytest, pybind11, scikit_build_core, rclpy, rosbags' \
    || die "$VENV cannot import the shared packages from $SHARED_SITE"
  stamp_set env "$SHARED $VENV"
fi
PIP=("$VENV/bin/python" -m pip --no-input --disable-pip-version-check)

# ---------------------------------------------------------------- d. editable project packages
pkg_hash="$(cd "$ROOT" && for p in "${PACKAGES[@]}"; do
  for f in "$p/setup.py" "$p/setup.cfg" "$p/package.xml"; do
    [ -f "$f" ] && sha256sum "$f" || echo "absent $f"
  done
done | hash_stdin)"
if ! stamp_ok packages "$pkg_hash" || [ ! -x "$VENV/bin/lit" ]; then
  say "installing ${PACKAGES[*]} into .venv (editable)"
  editable=()
  for p in "${PACKAGES[@]}"; do editable+=(-e "$ROOT/$p"); done
  # --use-pep517: a PEP 660 editable install puts console scripts into .venv/bin; the legacy
  # `setup.py develop` path would obey setup.cfg's ament script_dir ($base/lib/<pkg>) instead.
  # editable_mode=compat: put each project dir on sys.path through a .pth file. The default import
  # hook loses against the directory of the same name in the checkout root (e.g. ./lit_planner),
  # which Python then imports as an empty namespace package whenever the root is on sys.path.
  log="$VENV/lit-packages-install.log"
  if ! "${PIP[@]}" install --no-deps --no-build-isolation --use-pep517 \
      --config-settings editable_mode=compat "${editable[@]}" >"$log" 2>&1; then
    tail -n 30 "$log" >&2
    die "editable install failed; full log: $log"
  fi
  if [ ! -x "$VENV/bin/lit" ]; then
    say "pip did not create .venv/bin/lit; writing a launcher"
    printf '#!%s\nimport sys\nfrom lit_planner.cli import main\nsys.exit(main())\n' \
      "$VENV/bin/python" >"$VENV/bin/lit"
    chmod +x "$VENV/bin/lit"
  fi
  stamp_set packages "$pkg_hash"
fi

# ---------------------------------------------------------------- e. C++ core
CORE="$ROOT/lit_planner/core"
# Build trees are left out: build/ (this one) and build-*/ (lit test --sanitize's, whose ctest
# rewrites its logs at every run: each next ./lit rebuilt the core).
core_hash="$( { echo "deps $DEPS_KEY"; cd "$CORE" \
  && find . \( -path ./build -o -path './build-*' \) -prune -o -type f -print0 \
  | LC_ALL=C sort -z | xargs -0 -r sha256sum; } | hash_stdin)"
# Also rebuild when the installed module or the ctest tree went missing behind the stamp's back.
if ! stamp_ok core "$core_hash" \
    || ! compgen -G "$VENV/lib/python3*/site-packages/lit_core*.so" >/dev/null \
    || ! compgen -G "$CORE/build/*/CTestTestfile.cmake" >/dev/null; then
  say "building the C++ core (lit_planner/core) — incremental in lit_planner/core/build/"
  log="$VENV/lit-core-build.log"
  pybind11_dir="$("$VENV/bin/python" -m pybind11 --cmakedir)"
  start=$SECONDS
  if ! CMAKE_GENERATOR=Ninja CMAKE_BUILD_PARALLEL_LEVEL="${CMAKE_BUILD_PARALLEL_LEVEL:-$(nproc)}" \
      "${PIP[@]}" install -v --no-deps --no-build-isolation \
      --config-settings=cmake.define.pybind11_DIR="$pybind11_dir" "$CORE" >"$log" 2>&1; then
    rm -f "$STAMPS/core"
    { echo "----- error lines of $log -----"
      grep -E -m 15 '(error|Error|ERROR)[: ]' "$log" \
        | grep -v -E 'subprocess-exited|originates from a subprocess|ERROR: (Failed|Could not) build' \
        || true
      echo "----- last 25 lines of $log -----"
      tail -n 25 "$log"; } >&2
    die "C++ core build failed; full log: $log"
  fi
  "$VENV/bin/python" -c 'import lit_core' \
    || die "lit_core was installed but does not import; build log: $log"
  say "C++ core built and installed in $((SECONDS - start)) s"
  stamp_set core "$core_hash"
fi
