#!/usr/bin/env bash
# A one-node Slurm cluster from Debian's packages for the project's tests, as root and without
# systemd: every file it makes (configs, munge key and socket, state, logs, pid files) lives in
# one folder, and it stops only what it started, by its pid files.
#   scripts/slurm_cluster.sh available    exit 0 if Slurm can be installed and run here, else say
#                                         why and exit 1
#   scripts/slurm_cluster.sh install      install what is missing (slurmctld slurmd slurm-client
#                                         munge); quick when all is there
#   scripts/slurm_cluster.sh start DIR    start munged, slurmctld and slurmd; wait for the node;
#                                         clients then need `source DIR/env.sh` (SLURM_CONF)
#   scripts/slurm_cluster.sh stop DIR     cancel its jobs and stop the daemons again
# Several clusters can run at once (each in its own folder, on the first free pair of ports
# from 6817). A task sees SLURM_ARRAY_JOB_ID, SLURM_ARRAY_TASK_ID/COUNT/MIN/MAX/STEP.
set -euo pipefail

packages=(slurmctld slurmd slurm-client munge)

die() {
  echo "slurm_cluster: $*" >&2
  exit 1
}

missing_packages() {
  local p status
  for p in "${packages[@]}"; do
    status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
    [[ $status == "install ok installed" ]] || echo "$p"
  done
}

available() {
  [[ $(id -u) -eq 0 ]] || die "needs root (the daemons run as root)"
  command -v dpkg-query >/dev/null || die "not a Debian system (no dpkg-query)"
  [[ -z $(missing_packages) ]] && return 0
  command -v apt-get >/dev/null || die "Slurm is not installed and there is no apt-get"
  apt-cache show slurmd >/dev/null 2>&1 || die "Slurm is not installed and apt has no slurmd"
}

install() {
  local missing
  mapfile -t missing < <(missing_packages)
  if ((${#missing[@]} == 0)); then
    echo "slurm_cluster: ${packages[*]} already installed"
    return 0
  fi
  [[ $(id -u) -eq 0 ]] || die "installing ${missing[*]} needs root"
  # Package scripts must not start the services: the cluster is started by `start`.
  local policy=/usr/sbin/policy-rc.d made_policy=""
  if [[ ! -e $policy ]]; then
    printf '#!/bin/sh\nexit 101\n' >"$policy"
    chmod +x "$policy"
    made_policy=1
  fi
  export DEBIAN_FRONTEND=noninteractive
  local log status=0
  log=$(mktemp)
  local get=(apt-get install -y -q --no-install-recommends "${missing[@]}")
  # The package lists are updated only when installing from them fails.
  { "${get[@]}" >"$log" 2>&1 ||
    { apt-get update -q >"$log" 2>&1 && "${get[@]}" >"$log" 2>&1; }; } || status=$?
  [[ -z $made_policy ]] || rm -f "$policy"
  local why
  why=$(grep -E '^(E|W):' "$log" | tail -n 1 || true)
  [[ -n $why ]] || why=$(tail -n 1 "$log")
  rm -f "$log"
  ((status == 0)) || die "apt-get could not install ${missing[*]}: $why"
  echo "slurm_cluster: installed ${missing[*]}"
}

# The state of process $1 (R, S, Z, ...) and its name, or failure when there is none.
proc_state() {
  local stat
  { read -r stat <"/proc/$1/stat"; } 2>/dev/null || return 1
  local name=${stat#*(}
  name=${name%)*}
  stat=${stat##*) }
  echo "${stat%% *} $name"
}

# True while process $1 runs (a zombie has exited: where pid 1 reaps slowly, a stopped daemon
# stays one for up to 2 s), and, given $2, is named $2 (so a reused pid is never taken for it).
running() {
  local state name
  read -r state name < <(proc_state "$1") || return 1
  [[ $state != Z && ( $# -lt 2 || $name == "$2" ) ]]
}

# Starts `$@` in the background with every descriptor redirected (so that a caller waiting for
# our output, such as ctest, is not held by the daemon) and records its pid.
launch() {
  local pidfile=$1 log=$2
  shift 2
  "$@" </dev/null >>"$log" 2>&1 &
  echo $! >"$pidfile"
}

# The pid recorded for daemon $2 of cluster $1, if that daemon still runs.
daemon_pid() {
  local pidfile=$1/pids/$2.pid pid
  [[ -f $pidfile ]] || return 1
  pid=$(<"$pidfile")
  [[ $pid =~ ^[0-9]+$ ]] && running "$pid" "$2" && echo "$pid"
}

# Stops daemons $2... of cluster $1: SIGTERM, then SIGKILL for those still running after 10 s.
stop_daemons() {
  local dir=$1 name pid signal
  shift
  local -A pids=()
  for name in "$@"; do
    if pid=$(daemon_pid "$dir" "$name"); then
      kill -TERM "$pid" 2>/dev/null || true
      pids[$name]=$pid
    fi
  done
  for signal in KILL ""; do
    for _ in $(seq 100); do
      for name in "${!pids[@]}"; do
        running "${pids[$name]}" "$name" || unset "pids[$name]"
      done
      ((${#pids[@]} > 0)) || break
      sleep 0.1
    done
    [[ -n $signal ]] || break
    for name in "${!pids[@]}"; do
      echo "slurm_cluster: $name (${pids[$name]}) did not stop in 10 s: SIGKILL" >&2
      kill -KILL "${pids[$name]}" 2>/dev/null || true
    done
  done
  for name in "$@"; do rm -f "$dir/pids/$name.pid"; done
}

# The slurmstepds of cluster $1 (they write to DIR/log/slurmd.log).
stepds() {
  local pid fd
  for pid in $(pgrep -x slurmstepd || true); do
    for fd in /proc/"$pid"/fd/*; do
      if [[ $(readlink "$fd" 2>/dev/null) == "$1/log/slurmd.log" ]]; then
        echo "$pid"
        break
      fi
    done
  done
}

# Cancels every job of cluster $1 while its daemons run and waits up to 10 s for them to end;
# then kills whatever is left of them: its slurmstepds and all their descendants.
end_jobs() {
  local dir=$1 ids
  if [[ -f $dir/slurm.conf ]] && daemon_pid "$dir" slurmctld >/dev/null; then
    export SLURM_CONF=$dir/slurm.conf
    ids=$(squeue -h -o %F 2>/dev/null | sort -u | tr '\n' ' ' || true)
    if [[ -n ${ids// /} ]]; then
      # shellcheck disable=SC2086
      scancel $ids 2>/dev/null || true
      for _ in $(seq 100); do
        [[ -n $(squeue -h -o %i 2>/dev/null || true) ]] || break
        sleep 0.1
      done
    fi
  fi
  local -a left=()
  for _ in $(seq 20); do
    mapfile -t left < <(stepds "$dir")
    ((${#left[@]} > 0)) || return 0
    sleep 0.1
  done
  local -A children=()
  local stat ppid pid
  for stat in /proc/[0-9]*/stat; do
    { read -r ppid <"$stat"; } 2>/dev/null || continue
    ppid=${ppid##*) }
    read -r _ ppid _ <<<"$ppid"
    children[$ppid]+=" ${stat//[^0-9]/}"
  done
  local -a all=()
  while ((${#left[@]} > 0)); do
    pid=${left[0]}
    left=("${left[@]:1}")
    all+=("$pid")
    # shellcheck disable=SC2206
    left+=(${children[$pid]:-})
  done
  echo "slurm_cluster: jobs still running after scancel: SIGKILL to ${all[*]}" >&2
  kill -KILL "${all[@]}" 2>/dev/null || true
}

stop() {
  local dir=$1
  [[ -d $dir/pids ]] || return 0
  dir=$(cd "$dir" && pwd -P)
  end_jobs "$dir"
  stop_daemons "$dir" slurmd slurmctld
  stop_daemons "$dir" munged
}

# The TCP ports this machine listens on, one a line.
listening_ports() {
  local address state
  while read -r _ address _ state _; do
    if [[ $state == 0A ]]; then echo $((16#${address##*:})); fi
  done < <(cat /proc/net/tcp /proc/net/tcp6 2>/dev/null)
}

# True if this machine listens on TCP port $1.
listens() {
  local port
  for port in $(listening_ports); do
    if [[ $port == "$1" ]]; then return 0; fi
  done
  return 1
}

# The first of 6817, 6819, ... that is, with the next port, not listened on: SlurmctldPort and
# SlurmdPort.
free_ports() {
  local -A used=()
  local port
  for port in $(listening_ports); do used[$port]=1; done
  for ((port = 6817; port < 7217; port += 2)); do
    if [[ -z ${used[$port]:-} && -z ${used[$((port + 1))]:-} ]]; then
      echo "$port"
      return 0
    fi
  done
  die "no free pair of TCP ports in 6817-7218"
}

start() {
  local dir=$1
  [[ $dir != *[[:space:]]* ]] || die "the folder must not contain spaces: $dir"
  command -v slurmctld >/dev/null || die "Slurm is not installed: run $0 install"
  mkdir -p "$dir"
  dir=$(cd "$dir" && pwd -P)
  stop "$dir"
  rm -rf "${dir:?}"/{munge-key,munge-run,state,spool,log,pids,slurm.conf,env.sh}
  mkdir -p "$dir"/{munge-key,munge-run,state,spool,log,pids}
  chmod 0700 "$dir/munge-key"
  chmod 0755 "$dir/munge-run"
  dd if=/dev/urandom of="$dir/munge-key/munge.key" bs=1024 count=1 status=none
  chmod 0400 "$dir/munge-key/munge.key"
  local socket=$dir/munge-run/munge.socket.2
  launch "$dir/pids/munged.pid" "$dir/log/munged.out" munged --foreground --force \
    --socket="$socket" --key-file="$dir/munge-key/munge.key" \
    --pid-file="$dir/munge-run/munged.pid" --log-file="$dir/log/munged.log" \
    --seed-file="$dir/munge-key/munged.seed"
  for _ in $(seq 100); do
    [[ -S $socket ]] && break
    sleep 0.05
  done
  if [[ ! -S $socket ]]; then
    tail -n 5 "$dir"/log/munged.* >&2 || true
    stop "$dir"
    die "munged did not start (logs above)"
  fi

  local host node name port
  host=$(hostname -s)
  node=$(slurmd -C | sed -n 's/^\(NodeName=[^ ]*\) \(.*\)$/\1 NodeAddr=127.0.0.1 \2/p' |
    sed 's/ UpTime=.*//')
  [[ -n $node ]] || die "slurmd -C did not describe this node"
  name=$(sed -n 's/^NodeName=\([^ ]*\).*/\1/p' <<<"$node")
  port=$(free_ports)
  # MinJobAge stays at its default (300 s): `sbatch --wait` would look at the job every 2 s (not
  # after 2 s, 10 s, 42 s, 74 s, ...) with MinJobAge <= 5, but it may read a task's exit code only
  # once every task has finished, and by then a failed task's record can be gone: it exits 0.
  cat >"$dir/slurm.conf" <<CONF
ClusterName=phongfit
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/state/slurmctld.pid
SlurmdPidFile=$dir/spool/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
$node State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
  printf 'export SLURM_CONF=%q\n' "$dir/slurm.conf" >"$dir/env.sh"
  export SLURM_CONF=$dir/slurm.conf
  # slurmd and sinfo wait 1 s before they try again to reach a slurmctld that does not listen yet.
  launch "$dir/pids/slurmctld.pid" "$dir/log/slurmctld.out" slurmctld -D -i -f "$SLURM_CONF"
  local why="the node did not become idle in 30 s" daemons=(slurmctld) daemon
  for _ in $(seq 600); do
    if [[ ${#daemons[@]} -eq 1 ]] && listens "$port"; then
      launch "$dir/pids/slurmd.pid" "$dir/log/slurmd.out" slurmd -D -N "$name" -f "$SLURM_CONF"
      daemons+=(slurmd)
    fi
    if [[ ${#daemons[@]} -eq 2 && $(sinfo -h -o %t 2>/dev/null || true) == idle ]]; then
      echo "$dir/env.sh"
      return 0
    fi
    for daemon in "${daemons[@]}"; do
      running "$(<"$dir/pids/$daemon.pid")" || why="$daemon exited"
    done
    [[ $why == "the node did not become idle in 30 s" ]] || break
    sleep 0.05
  done
  tail -n 5 "$dir"/log/* >&2 || true
  stop "$dir"
  die "$why (logs above)"
}

case ${1:-} in
available) available ;;
install) install ;;
start) [[ $# -eq 2 ]] || die "usage: $0 start DIR"; start "$2" ;;
stop) [[ $# -eq 2 ]] || die "usage: $0 stop DIR"; stop "$2" ;;
*) die "usage: $0 available | install | start DIR | stop DIR" ;;
esac
