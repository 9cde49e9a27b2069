#!/bin/sh
# What `python -m codegen sanitize` needs beyond gcc: clang with libFuzzer and the ASan/UBSan
# runtimes. Does nothing when they work; otherwise installs Debian's clang and libclang-rt-dev
# (as root, with apt-get), or says what to install. Run by `make test` (target c-tools).
set -eu
cc="${FUZZ_CC:-clang}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf 'int LLVMFuzzerTestOneInput(const unsigned char *d, unsigned long n) { (void)d; (void)n; return 0; }\n' >"$tmp/f.c"
probe() { "$cc" -fsanitize=fuzzer,address,undefined "$tmp/f.c" -o "$tmp/f" >/dev/null 2>&1; }
probe && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "c-tools: installing clang and libclang-rt-dev (libFuzzer, sanitizer runtimes) with apt-get"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq clang libclang-rt-dev >/dev/null
    probe && exit 0
fi
echo "c-tools: $cc cannot build a libFuzzer target with -fsanitize=fuzzer,address,undefined;" \
     "install clang and its compiler-rt (Debian: apt-get install clang libclang-rt-dev)" >&2
exit 1
