#!/usr/bin/env bash
# Print the path of a working Python >= 3.12 interpreter, or fail with a message.
#
# Candidates on PATH are executed, not just located: pyenv shims such as
# python3.12 exist on PATH but fail unless PYENV_VERSION selects a version.
# After PATH, fall back to interpreters installed under `pyenv root`.
set -u

check='import sys; assert sys.version_info >= (3, 12)'

try() {
    local cand=$1
    if "$cand" -c "$check" >/dev/null 2>&1; then
        # Resolve to the real interpreter so the venv does not depend on shims.
        "$cand" -c 'import sys; print(sys.executable)'
        exit 0
    fi
}

for name in python3.13 python3.12 python3; do
    if path=$(command -v "$name" 2>/dev/null); then
        try "$path"
    fi
done

if command -v pyenv >/dev/null 2>&1; then
    root=$(pyenv root 2>/dev/null || true)
else
    root=${PYENV_ROOT:-$HOME/.pyenv}
fi
if [ -n "${root:-}" ]; then
    for cand in "$root"/versions/3.1[2-9]*/bin/python3; do
        [ -x "$cand" ] && try "$cand"
    done
fi

echo "hosid needs Python >= 3.12; none found on PATH or under pyenv" >&2
exit 1
