#!/usr/bin/env bash
# Links the CUDA build (`--features cuda`) on a machine that cannot reach GitHub.
#
# cubecl-cuda's PTX backend links LLVM 23.1 statically. Its build normally downloads
# tracel's prebuilt bundle from GitHub into ~/.local/share/tracel/tracel-llvm-23.1.0-4 and
# marks it installed with a sentinel file; on a machine that reaches only the Debian mirrors
# that download fails and the build stops. This script fills the same directory from
# Debian's own LLVM 23.1 packages (unstable: llvm-23, llvm-23-dev, libllvm23, and libpolly-23-dev because
# Debian links Polly into LLVM, so its `llvm-config --libs` names Polly), unpacked with
# `dpkg -x`, never installed, so the system's packages stay as they are.
#
# Two adjustments, both because the packages come from a newer Debian than the build machine:
# - Debian's static LLVM libraries were compiled against glibc 2.38+, whose headers rename
#   strtol and friends to `__isoc23_strtol` (C23 parsing of "0b" prefixes). An older glibc
#   lacks those names, so a tiny archive forwards them to the classic functions (LLVM never
#   parses binary literals through them); it is appended to `llvm-config --libs`.
# - `llvm-config --system-libs` names Z3 by an absolute path; it becomes `-lz3` so the
#   system's libz3-dev is used, and dropped by the linker when nothing references it.
#
#   scripts/llvm_offline.sh            # then: cargo build --release --features envision4d-cli/cuda
#   LLVM_DEBS=dir scripts/llvm_offline.sh   # .deb files already downloaded into dir
#
# It needs: apt-get, dpkg, cc, ar, and the -dev packages zlib1g-dev libzstd-dev libxml2-dev
# libz3-dev (installed when missing). Run it once; it refuses to touch a real tracel bundle.
set -euo pipefail
VERSION=23.1.0-4
TRACEL=${XDG_DATA_HOME:-$HOME/.local/share}/tracel/tracel-llvm-$VERSION
STORE=${LLVM_STORE:-$HOME/.cache/envision4d-llvm}
LLVM=$STORE/usr/lib/llvm-23
SENTINEL=$TRACEL/.tracel-llvm-installed

# tracel's bundle ships llvm-config as a program; ours is a shell script.
if [ -e "$SENTINEL" ] && head -c 4 "$TRACEL/bin/llvm-config" 2>/dev/null | grep -q ELF; then
  echo "llvm_offline: $TRACEL already holds tracel's own bundle; nothing to do" >&2
  exit 0
fi

missing=()
for p in zlib1g-dev libzstd-dev libxml2-dev libz3-dev; do
  dpkg -s "$p" > /dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  apt-get install -y -qq "${missing[@]}"
fi

if [ ! -x "$LLVM/bin/llvm-config" ] || [ ! -e "$LLVM/lib/libPolly.a" ]; then
  debs=${LLVM_DEBS:-}
  if [ -z "$debs" ]; then
    # Debian unstable's index in a private apt state: nothing of the system's apt changes.
    apt_dir=$(mktemp -d)
    debs=$apt_dir/debs
    mkdir -p "$apt_dir/lists/partial" "$apt_dir/cache/archives/partial" "$debs"
    echo "deb [signed-by=/usr/share/keyrings/debian-archive-keyring.gpg]" \
      "http://deb.debian.org/debian unstable main" > "$apt_dir/sources.list"
    o=(-oDir::Etc::SourceList="$apt_dir/sources.list" -oDir::Etc::SourceParts=/dev/null
      -oDir::State::Lists="$apt_dir/lists" -oDir::Cache="$apt_dir/cache")
    apt-get "${o[@]}" update -qq
    (cd "$debs" && apt-get "${o[@]}" download llvm-23 llvm-23-dev libllvm23 libpolly-23-dev)
  fi
  mkdir -p "$STORE"
  for f in "$debs"/llvm-23_*.deb "$debs"/llvm-23-dev_*.deb "$debs"/libllvm23_*.deb \
    "$debs"/libpolly-23-dev_*.deb; do
    dpkg -x "$f" "$STORE"
  done
fi
version=$("$LLVM/bin/llvm-config" --version)
case "$version" in
  23.1.*) ;;
  *) echo "llvm_offline: $LLVM is LLVM $version; cubecl-cuda needs 23.1" >&2; exit 1 ;;
esac

# The glibc 2.38 names Debian's archives reference, forwarded to the classic parsers.
work=$(mktemp -d)
cat > "$work/compat.c" << 'EOF'
#include <stdlib.h>
long __isoc23_strtol(const char *s, char **e, int b) { return strtol(s, e, b); }
long long __isoc23_strtoll(const char *s, char **e, int b) { return strtoll(s, e, b); }
unsigned long __isoc23_strtoul(const char *s, char **e, int b) { return strtoul(s, e, b); }
unsigned long long __isoc23_strtoull(const char *s, char **e, int b) { return strtoull(s, e, b); }
EOF
cc -O2 -fPIC -c "$work/compat.c" -o "$work/compat.o"
ar rcs "$LLVM/lib/libenvision4d_glibc_compat.a" "$work/compat.o"
rm -rf "$work"

# tracel's layout: bin/llvm-config under the bundle's directory; ours forwards to Debian's
# (which reports its own lib and include directories) with the two adjustments above.
mkdir -p "$TRACEL/bin"
cat > "$TRACEL/bin/llvm-config.tmp" << EOF
#!/bin/sh
# envision4d scripts/llvm_offline.sh: Debian's LLVM $version standing in for tracel's bundle.
out=\$("$LLVM/bin/llvm-config" "\$@") || exit \$?
case " \$* " in
  *" --system-libs "*) out=\$(printf '%s' "\$out" | sed 's#[^ ]*/libz3\\.so#-lz3#') ;;
  *" --libs "*) out="\$out -lenvision4d_glibc_compat" ;;
esac
printf '%s\n' "\$out"
EOF
chmod +x "$TRACEL/bin/llvm-config.tmp"
mv "$TRACEL/bin/llvm-config.tmp" "$TRACEL/bin/llvm-config"
touch "$SENTINEL"
echo "llvm_offline: LLVM $version from Debian at $LLVM, standing in at $TRACEL"
