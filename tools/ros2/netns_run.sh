#!/usr/bin/env bash
# Run a command inside a fresh, private network namespace that has only loopback
# (up, multicast on, with a 224.0.0.0/4 route so DDS discovery works on it).
#
#   tools/ros2/netns_run.sh CMD [ARGS...]
#
# Every process that opens a DDS participant (tests, demos, rclpy peers) must run
# like this: discovery multicasts out of every interface, and nothing may leave
# the machine. Namespaces made by separate calls are isolated from each other, so
# processes that must see each other have to be started by ONE call (e.g. a
# `bash -c '...'` that starts all of them).
#
# If CD_NETNS=1 is already set (we are inside such a namespace) CMD is exec'd
# directly, after checking that loopback really is the only interface.
# Exit status: that of CMD (1 if unshare itself fails, 126 if CD_NETNS=1 but
# other interfaces are visible).
set -euo pipefail

if [[ $# -eq 0 ]]; then
    echo "usage: $0 CMD [ARGS...]" >&2
    exit 2
fi

# /proc/net/dev lists the interfaces of the *current* network namespace
# (/sys/class/net may still show the mount's original namespace).
interfaces() { tail -n +3 /proc/net/dev | cut -d: -f1 | tr -d ' ' | tr '\n' ' '; }
only_loopback() { [[ "$(interfaces)" == "lo " ]]; }

if [[ "${CD_NETNS:-}" == "1" ]]; then
    if ! only_loopback; then
        echo "netns_run: CD_NETNS=1 but interfaces other than lo are visible: $(interfaces)" >&2
        exit 126
    fi
    exec "$@"
fi

if ! command -v unshare >/dev/null || ! command -v ip >/dev/null; then
    echo "netns_run: needs unshare (util-linux) and ip (iproute2)" >&2
    exit 1
fi

# The inner script sets loopback up, then replaces itself with CMD ("$@").
exec unshare -n -- bash -c '
    set -e
    ip link set lo up
    ip link set lo multicast on
    ip route add 224.0.0.0/4 dev lo
    export CD_NETNS=1
    exec "$@"
' netns_run "$@"
