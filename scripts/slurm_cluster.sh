#!/usr/bin/env bash
# A one-node Slurm cluster from Debian's packages for the project's tests, as root and without
# systemd: every file it makes (configs, munge key and socket, state, logs, pid files) lives in
# one folder, and it stops only the daemons it started, by their pid files.
#   scripts/slurm_cluster.sh available    exit 0 if Slurm can be installed and run here
#   scripts/slurm_cluster.sh install      install what is missing (slurmctld slurmd slurm-client
#                                         munge); quick when all is there
#   scripts/slurm_cluster.sh start DIR    start munged, slurmctld and slurmd; wait for the node;
#                                         clients then need `source DIR/env.sh` (SLURM_CONF)
#   scripts/slurm_cluster.sh stop DIR     stop them again
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
  ((${#missing[@]} > 0)) || return 0
  echo "slurm_cluster: installing ${missing[*]}"
  # Package scripts must not start the services: the cluster is started by `start`.
  local policy=/usr/sbin/policy-rc.d made_policy=""
  if [[ ! -e $policy ]]; then
    printf '#!/bin/sh\nexit 101\n' >"$policy"
    chmod +x "$policy"
    made_policy=1
  fi
  export DEBIAN_FRONTEND=noninteractive
  local status=0
  local get=(apt-get install -y -qq --no-install-recommends "${missing[@]}")
  { "${get[@]}" >/dev/null 2>&1 || { apt-get update -qq && "${get[@]}" >/dev/null; }; } || status=$?
  [[ -z $made_policy ]] || rm -f "$policy"
  ((status == 0)) || die "apt-get could not install ${missing[*]}"
}

# Starts `$@` in the background with every descriptor redirected (so that a caller waiting for
# our output, such as ctest, is not held by the daemon) and records its pid.
launch() {
  local pidfile=$1 log=$2
  shift 2
  "$@" </dev/null >>"$log" 2>&1 &
  echo $! >"$pidfile"
}

stop() {
  local dir=$1 pidfile pid
  [[ -d $dir ]] || return 0
  for pidfile in "$dir"/pids/slurmd.pid "$dir"/pids/slurmctld.pid "$dir"/pids/munged.pid; do
    [[ -f $pidfile ]] || continue
    pid=$(<"$pidfile")
    if kill -0 "$pid" 2>/dev/null; then
      kill -TERM "$pid" 2>/dev/null || true
      for _ in $(seq 100); do
        kill -0 "$pid" 2>/dev/null || break
        sleep 0.1
      done
      kill -KILL "$pid" 2>/dev/null || true
    fi
    rm -f "$pidfile"
  done
}

start() {
  local dir=$1
  mkdir -p "$dir"
  dir=$(cd "$dir" && pwd)
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
  [[ -S $socket ]] || { tail -5 "$dir"/log/munged.* >&2; die "munged did not start"; }

  local host node name
  host=$(hostname -s)
  node=$(slurmd -C | sed -n 's/^\(NodeName=[^ ]*\) \(.*\)$/\1 NodeAddr=127.0.0.1 \2/p' |
    sed 's/ UpTime=.*//')
  [[ -n $node ]] || die "slurmd -C did not describe this node"
  name=$(sed -n 's/^NodeName=\([^ ]*\).*/\1/p' <<<"$node")
  cat >"$dir/slurm.conf" <<CONF
ClusterName=phongfit
SlurmctldHost=$host(127.0.0.1)
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
  launch "$dir/pids/slurmctld.pid" "$dir/log/slurmctld.out" slurmctld -D -i -f "$SLURM_CONF"
  launch "$dir/pids/slurmd.pid" "$dir/log/slurmd.out" slurmd -D -N "$name" -f "$SLURM_CONF"
  for _ in $(seq 300); do
    if sinfo -h -o %t 2>/dev/null | grep -qx idle; then
      echo "$dir/env.sh"
      return 0
    fi
    sleep 0.1
  done
  tail -n 5 "$dir"/log/* >&2 || true
  stop "$dir"
  die "the node did not become idle in 30 s (logs above)"
}

case ${1:-} in
available) available ;;
install) install ;;
start) [[ $# -eq 2 ]] || die "usage: $0 start DIR"; start "$2" ;;
stop) [[ $# -eq 2 ]] || die "usage: $0 stop DIR"; stop "$2" ;;
*) die "usage: $0 available | install | start DIR | stop DIR" ;;
esac
