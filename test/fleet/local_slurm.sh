#!/usr/bin/env bash
# local_slurm.sh - a throw-away single-node Slurm cluster on localhost
# (munged + slurmctld + slurmd) for the fleet test (test/fleet/slurm_fleet_test.sh), run as
# root; docs/fleet.md.
#
#   local_slurm.sh install           install Debian packages if missing
#   local_slurm.sh start STATE_DIR   write config under STATE_DIR, start daemons,
#                                    wait until the node is idle
#   local_slurm.sh stop  STATE_DIR   stop exactly the daemons started for STATE_DIR
#   local_slurm.sh status STATE_DIR  show pids and sinfo
#
# After `start`, clients need:   . STATE_DIR/env.sh      (exports SLURM_CONF)
# The munge socket path is passed to Slurm via AuthInfo=socket=... in
# slurm.conf, so SLURM_CONF is all a Slurm client needs.
#
# Environment knobs (all optional):
#   LOCAL_SLURM_CPUS=2             CPUs of the single node
#   LOCAL_SLURM_TIMEOUT=30         seconds to wait for each daemon / the node
#   LOCAL_SLURM_CTLD_PORT=6817     slurmctld port
#   LOCAL_SLURM_SLURMD_PORT=6818   slurmd port
#
# No systemd needed. Daemons are started with their own daemonisation and pid
# files under STATE_DIR; `stop` only kills a pid whose command line still
# mentions STATE_DIR, so a recycled pid is never killed.

set -u

PROG=${0##*/}
CPUS=${LOCAL_SLURM_CPUS:-2}
TIMEOUT=${LOCAL_SLURM_TIMEOUT:-30}
CTLD_PORT=${LOCAL_SLURM_CTLD_PORT:-6817}
SLURMD_PORT=${LOCAL_SLURM_SLURMD_PORT:-6818}
PACKAGES="munge slurmctld slurmd slurm-client"

log() { printf '%s: %s\n' "$PROG" "$*"; }
err() { printf '%s: ERROR: %s\n' "$PROG" "$*" >&2; }
die() { err "$*"; exit 1; }

# Print the last lines of a log file to stderr.
show_log() {
    local f=$1
    if [ -s "$f" ]; then
        printf '%s: ---- last lines of %s ----\n' "$PROG" "$f" >&2
        tail -n 25 "$f" >&2
        printf '%s: ---- end of %s ----\n' "$PROG" "$f" >&2
    else
        printf '%s: (log %s is empty or missing)\n' "$PROG" "$f" >&2
    fi
}

need_root() {
    [ "$(id -u)" = 0 ] || die "must run as root (SlurmUser=root, munged key ownership)"
}

# ----------------------------------------------------------------- install --
missing_packages() {
    local p miss=""
    for p in $PACKAGES; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' \
            || miss="$miss $p"
    done
    echo "$miss"
}

have_binaries() {
    local b
    for b in munged slurmctld slurmd sbatch squeue sinfo scancel scontrol; do
        command -v "$b" >/dev/null 2>&1 || PATH=$PATH:/usr/sbin:/sbin command -v "$b" >/dev/null 2>&1 || return 1
    done
}

cmd_install() {
    need_root
    export DEBIAN_FRONTEND=noninteractive
    local miss t0 rc added_policy=0
    miss=$(missing_packages)
    if [ -z "${miss// /}" ]; then
        log "packages already installed: $PACKAGES"
    else
        log "installing:$miss"
        t0=$(date +%s)
        # Keep package maintainer scripts from starting system-wide daemons
        # (munge's init script would start a munged on /run/munge).
        if [ ! -e /usr/sbin/policy-rc.d ]; then
            printf '#!/bin/sh\nexit 101\n' > /usr/sbin/policy-rc.d
            chmod 755 /usr/sbin/policy-rc.d
            added_policy=1
        fi
        # shellcheck disable=SC2086
        apt-get install -y --no-install-recommends $miss
        rc=$?
        if [ $rc -ne 0 ]; then
            log "apt-get install failed (rc=$rc); running apt-get update and retrying"
            apt-get update && apt-get install -y --no-install-recommends $miss
            rc=$?
        fi
        [ $added_policy = 1 ] && rm -f /usr/sbin/policy-rc.d
        [ $rc -eq 0 ] || die "apt-get install$miss failed (rc=$rc)"
        log "installed:$miss in $(( $(date +%s) - t0 )) s"
    fi
    have_binaries || die "packages installed but some binaries are missing"
    log "usable: $(slurmctld -V 2>/dev/null), munge $(dpkg-query -W -f='${Version}' munge)"
}

# ------------------------------------------------------------ pid handling --
# pid_alive NAME DIR: prints pid if pid file DIR/run/NAME.pid names a live
# process whose command line mentions STATE_DIR (so it is ours).
pid_alive() {
    local name=$1 dir=$2 pf pid
    pf=$dir/run/$name.pid
    [ -r "$pf" ] || return 1
    pid=$(tr -dc '0-9' < "$pf")
    [ -n "$pid" ] && [ -d "/proc/$pid" ] || return 1
    tr '\0' ' ' < "/proc/$pid/cmdline" 2>/dev/null | grep -qF -- "$dir/" || return 1
    echo "$pid"
}

# stop_daemon NAME DIR
stop_daemon() {
    local name=$1 dir=$2 pid i
    pid=$(pid_alive "$name" "$dir") || { rm -f "$dir/run/$name.pid"; return 0; }
    log "stopping $name (pid $pid)"
    kill -TERM "$pid" 2>/dev/null
    for i in $(seq 1 $((TIMEOUT * 5))); do
        [ -d "/proc/$pid" ] || break
        # zombie (our own child) counts as gone
        grep -q '^State:.*Z' "/proc/$pid/status" 2>/dev/null && break
        sleep 0.2
    done
    if [ -d "/proc/$pid" ] && ! grep -q '^State:.*Z' "/proc/$pid/status" 2>/dev/null; then
        log "$name (pid $pid) did not exit after SIGTERM, sending SIGKILL"
        kill -KILL "$pid" 2>/dev/null
        for i in $(seq 1 25); do [ -d "/proc/$pid" ] || break; sleep 0.2; done
    fi
    rm -f "$dir/run/$name.pid"
}

# wait_pidfile NAME DIR LOG: wait until the daemon wrote its pid file and is alive
wait_pidfile() {
    local name=$1 dir=$2 logf=$3 i
    for i in $(seq 1 $((TIMEOUT * 5))); do
        pid_alive "$name" "$dir" >/dev/null && return 0
        sleep 0.2
    done
    err "$name did not come up within ${TIMEOUT}s"
    show_log "$logf"
    return 1
}

port_busy() {
    # is a TCP listener on port $1? (/proc/net/tcp{,6}: state 0A = LISTEN)
    local hex
    hex=$(printf '%04X' "$1")
    cat /proc/net/tcp /proc/net/tcp6 2>/dev/null |
        awk -v p=":$hex" '$4 == "0A" && substr($2, length($2)-4) == p {f=1} END {exit !f}'
}

abs_dir() {
    mkdir -p "$1" || die "cannot create $1"
    (cd "$1" && pwd -P)
}

# start_daemon NAME DIR ARGS...: starts the Slurm daemon NAME with ARGS, waits for its pid
# file; on failure prints its logs, stops what was started and returns 1.
start_daemon() {
    local name=$1 dir=$2 rc
    shift 2
    "$name" "$@" > "$dir/log/$name.start.log" 2>&1
    rc=$?
    if [ $rc -ne 0 ]; then
        err "$name failed to start (rc=$rc)"
        show_log "$dir/log/$name.start.log"; show_log "$dir/log/$name.log"
        cmd_stop "$dir"; return 1
    fi
    wait_pidfile "$name" "$dir" "$dir/log/$name.log" || { cmd_stop "$dir"; return 1; }
    log "$name up (pid $(pid_alive "$name" "$dir"))"
}

# ------------------------------------------------------------------- start --
cmd_start() {
    need_root
    [ $# -ge 1 ] || die "usage: $PROG start STATE_DIR"
    have_binaries || die "Slurm/munge binaries missing; run '$PROG install' first"
    local dir host mem sock mdir t0 p
    t0=$(date +%s)
    dir=$(abs_dir "$1")
    case $dir in *[[:space:]]*) die "STATE_DIR must not contain white space: $dir";; esac

    # A previous run may have left daemons (no stop) and stale files.
    cmd_stop "$dir" >/dev/null 2>&1
    rm -rf "$dir/ctld" "$dir/slurmd" "$dir/run" "$dir/log"
    mkdir -p "$dir/ctld" "$dir/slurmd" "$dir/run" "$dir/log" "$dir/munge"
    # munged: key dir private (0700); socket dir must be 0755 (x for all,
    # writable only by the owner).
    chmod 700 "$dir/munge"
    chmod 755 "$dir" "$dir/ctld" "$dir/slurmd" "$dir/run" "$dir/log"

    for p in "$CTLD_PORT" "$SLURMD_PORT"; do
        port_busy "$p" && die "TCP port $p is already in use (another slurmctld/slurmd?). \
Stop it or set LOCAL_SLURM_CTLD_PORT / LOCAL_SLURM_SLURMD_PORT."
    done

    # ---- munge
    local key=$dir/munge/munge.key
    if [ ! -s "$key" ]; then
        if command -v mungekey >/dev/null 2>&1; then
            mungekey --create --keyfile="$key" --force >/dev/null 2>&1 ||
                dd if=/dev/urandom of="$key" bs=1024 count=1 2>/dev/null
        else
            dd if=/dev/urandom of="$key" bs=1024 count=1 2>/dev/null
        fi
    fi
    chown root:root "$key"; chmod 400 "$key"
    # Unix socket paths are limited to 107 bytes; fall back to a short dir.
    sock=$dir/run/munge.socket
    if [ ${#sock} -gt 100 ]; then
        mdir=/run/local_slurm_munge_$(printf '%s' "$dir" | cksum | cut -d' ' -f1)
        mkdir -p "$mdir"; chmod 755 "$mdir"
        sock=$mdir/munge.socket
        log "STATE_DIR path too long for a unix socket; munge socket is $sock"
    fi
    rm -f "$sock" "$sock.lock"
    local margs rc
    margs=(--socket="$sock" --key-file="$key" --pid-file="$dir/run/munged.pid"
           --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed"
           --num-threads=2)
    munged "${margs[@]}" > "$dir/log/munged.start.log" 2>&1
    rc=$?
    if [ $rc -ne 0 ] && grep -qiE 'insecure|inaccessible' "$dir/log/munged.start.log"; then
        # munged checks every parent directory of key/socket/log/pid files;
        # e.g. a world-writable build directory makes it refuse. It is a
        # throw-away test cluster, so retry with --force.
        log "munged refused insecure permissions ($(tail -n1 "$dir/log/munged.start.log")); retrying with --force"
        rm -f "$sock" "$sock.lock"
        munged --force "${margs[@]}" >> "$dir/log/munged.start.log" 2>&1
        rc=$?
    fi
    if [ $rc -ne 0 ]; then
        err "munged failed to start (rc=$rc)"
        show_log "$dir/log/munged.start.log"; show_log "$dir/log/munged.log"
        return 1
    fi
    wait_pidfile munged "$dir" "$dir/log/munged.log" || { cmd_stop "$dir"; return 1; }
    # check that munge works through our socket
    if ! munge --socket="$sock" -n 2>>"$dir/log/munged.start.log" |
            unmunge --socket="$sock" >/dev/null 2>>"$dir/log/munged.start.log"; then
        err "munge/unmunge round trip through $sock failed"
        show_log "$dir/log/munged.start.log"; show_log "$dir/log/munged.log"
        cmd_stop "$dir"; return 1
    fi
    log "munged up (pid $(pid_alive munged "$dir"), socket $sock)"

    # ---- slurm.conf
    host=$(hostname -s 2>/dev/null || hostname)
    [ -n "$host" ] || host=localhost
    # RealMemory in MB: 90% of MemTotal, at most what slurmd sees.
    mem=$(awk '/^MemTotal:/ {printf "%d", $2 / 1024 * 0.9}' /proc/meminfo)
    [ -n "$mem" ] && [ "$mem" -gt 0 ] || mem=500
    cat > "$dir/slurm.conf" <<EOF
# generated by $PROG for a single-node test cluster; state in $dir
ClusterName=localtest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$sock
StateSaveLocation=$dir/ctld
SlurmdSpoolDir=$dir/slurmd
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$dir/log/jobcomp.txt
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SlurmdParameters=config_overrides
MpiDefault=none
ReturnToService=2
MailProg=/bin/true
MinJobAge=600
InactiveLimit=0
KillWait=5
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=$host NodeAddr=127.0.0.1 NodeHostname=$host CPUs=$CPUS RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
EOF
    printf 'export SLURM_CONF=%s\n' "$dir/slurm.conf" > "$dir/env.sh"
    export SLURM_CONF=$dir/slurm.conf

    # ---- slurmctld, then slurmd (-c: forget jobs of any previous run)
    start_daemon slurmctld "$dir" -c -f "$dir/slurm.conf" || return 1
    start_daemon slurmd "$dir" -c -N "$host" -f "$dir/slurm.conf" || return 1

    # ---- wait for the node to be idle
    local i state=""
    for i in $(seq 1 $((TIMEOUT * 2))); do
        state=$(timeout 10 sinfo -h -N -n "$host" -o '%T' 2>/dev/null | head -n1)
        [ "$state" = idle ] && break
        sleep 0.5
    done
    if [ "$state" != idle ]; then
        err "node $host not idle after ${TIMEOUT}s (state: '${state:-none}')"
        timeout 10 sinfo -N -l >&2 2>&1
        timeout 10 scontrol show node "$host" >&2 2>&1
        show_log "$dir/log/slurmctld.log"; show_log "$dir/log/slurmd.log"
        cmd_stop "$dir"; return 1
    fi
    log "node $host idle with $CPUS CPUs after $(( $(date +%s) - t0 )) s"
    log "clients need:  export SLURM_CONF=$dir/slurm.conf   (or: . $dir/env.sh)"
    echo "export SLURM_CONF=$dir/slurm.conf"
}

# -------------------------------------------------------------------- stop --
cmd_stop() {
    [ $# -ge 1 ] || die "usage: $PROG stop STATE_DIR"
    local dir
    [ -d "$1" ] || { log "nothing to stop ($1 does not exist)"; return 0; }
    dir=$(cd "$1" && pwd -P)
    # Cancel leftover jobs so no slurmstepd/job processes outlive the cluster.
    if pid_alive slurmctld "$dir" >/dev/null && [ -r "$dir/slurm.conf" ]; then
        SLURM_CONF=$dir/slurm.conf timeout 10 scancel --full --quiet \
            --user=root >/dev/null 2>&1 || true
        local i
        for i in $(seq 1 25); do
            [ -z "$(SLURM_CONF=$dir/slurm.conf timeout 5 squeue -h -o %i 2>/dev/null)" ] && break
            sleep 0.2
        done
    fi
    stop_daemon slurmd "$dir"
    stop_daemon slurmctld "$dir"
    stop_daemon munged "$dir"
    # remove the short fallback socket dir (see start), if any
    local sd
    sd=$(sed -n 's|^AuthInfo=socket=\(/run/local_slurm_munge_[0-9]*\)/munge.socket$|\1|p' \
         "$dir/slurm.conf" 2>/dev/null)
    [ -n "$sd" ] && rm -rf "$sd"
    log "stopped (state kept in $dir)"
    return 0
}

cmd_status() {
    [ $# -ge 1 ] || die "usage: $PROG status STATE_DIR"
    local dir n pid rc=0
    dir=$(cd "$1" 2>/dev/null && pwd -P) || die "no such dir $1"
    for n in munged slurmctld slurmd; do
        if pid=$(pid_alive "$n" "$dir"); then log "$n running (pid $pid)"
        else log "$n not running"; rc=1; fi
    done
    [ $rc = 0 ] && SLURM_CONF=$dir/slurm.conf timeout 10 sinfo -N -l
    return $rc
}

case ${1:-} in
    install) shift; cmd_install "$@" ;;
    start)   shift; cmd_start "$@" ;;
    stop)    shift; cmd_stop "$@" ;;
    status)  shift; cmd_status "$@" ;;
    *) echo "usage: $PROG install | start STATE_DIR | stop STATE_DIR | status STATE_DIR" >&2; exit 2 ;;
esac
