#!/usr/bin/env bash
# Build toxiproxy (github.com/Shopify/toxiproxy, a fault-injection TCP proxy) for the fault matrix,
# tests/integration/test_fault_matrix.py, whose toxiproxy cases skip without it.
#
#   scripts/install_toxiproxy.sh            # -> ~/.cache/aioadept/bin/toxiproxy-server, toxiproxy-cli
#
# It is `go install` through the Go module proxy, renamed into one known place, where the test fixture looks:
#   AIOADEPT_TOOLS_DIR   where to put the binaries (default ~/.cache/aioadept/bin)
#   TOXIPROXY_VERSION    module version (default v2.5.0; v2.12.x has the same command paths)
# Needs Go (1.17 or newer). Takes about a minute on 2 cores when nothing is cached, seconds when the module and
# build caches are warm. Idempotent: an existing build of the same version is kept.
set -euo pipefail

version="${TOXIPROXY_VERSION:-v2.5.0}"
dest="${AIOADEPT_TOOLS_DIR:-$HOME/.cache/aioadept/bin}"
module="github.com/Shopify/toxiproxy/v2"

if ! command -v go >/dev/null 2>&1; then
    echo "install_toxiproxy.sh: 'go' not found; install Go from https://go.dev/dl/ and run again" >&2
    exit 1
fi

if [[ -x "$dest/toxiproxy-server" && -f "$dest/.toxiproxy-version" && "$(cat "$dest/.toxiproxy-version")" == "$version" ]]; then
    echo "toxiproxy $version already in $dest"
    exit 0
fi

mkdir -p "$dest"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# GOBIN: a scratch directory, because go install names the binaries after their directories (server, cli).
GOBIN="$work" go install "$module/cmd/server@$version" "$module/cmd/cli@$version"
install -m 0755 "$work/server" "$dest/toxiproxy-server"
install -m 0755 "$work/cli" "$dest/toxiproxy-cli"
echo "$version" > "$dest/.toxiproxy-version"
echo "installed toxiproxy $version: $dest/toxiproxy-server, $dest/toxiproxy-cli"
