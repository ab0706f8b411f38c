#!/usr/bin/env bash
# Print the path of a working Python 3.12 interpreter (the Makefile's finder; scenes.robocasa.environment mirrors it).
# Each candidate is run, so a pyenv shim whose global version is not 3.12 is passed over, and the real executable is
# printed. Order: pyenv's 3.12, python3.12 on PATH, pyenv's install folders, the OS's.
probe='import sys; assert sys.version_info[:2] == (3, 12); print(sys.executable)'
candidates=()
if command -v pyenv >/dev/null 2>&1; then candidates+=("$(pyenv which python3.12 2>/dev/null)"); fi
candidates+=("$(command -v python3.12 2>/dev/null)")
for root in "${PYENV_ROOT:-}" "$HOME/.pyenv"; do
  [ -n "$root" ] && candidates+=($(ls -d "$root"/versions/3.12*/bin/python3.12 2>/dev/null | sort -V -r))
done
candidates+=(/usr/local/bin/python3.12 /usr/bin/python3.12)
for c in "${candidates[@]}"; do
  [ -n "$c" ] && [ -x "$c" ] && "$c" -c "$probe" 2>/dev/null && exit 0
done
exit 1
