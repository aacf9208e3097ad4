#!/usr/bin/env bash
# A throwaway single-node Slurm cluster on this machine, all of it inside one folder: its own munge key
# and munged socket, slurm.conf, state, spool, logs and pid files, free ports, no cgroups, no accounting.
# The batch test (tests/slurm/slurm_batch_test.sh) runs on it, and a user can try watergs_batch.sh with it.
#   local_slurm.sh start DIR   starts munged, slurmctld and slurmd; prints 'export SLURM_CONF=DIR/slurm.conf'
#                              once the node accepts jobs (exit 3 with the reason when the daemons cannot run)
#   local_slurm.sh stop DIR    stops the daemons started in DIR (by their pid files) and waits for them
# Needs the Debian packages slurm-wlm and munge (scripts/install_deps.sh --tests). Slurm runs as the calling user.
set -euo pipefail
script_name="$(basename "$0")"

die() {
  echo "$script_name: error: $*" >&2
  exit 1
}
cannot_run() {  # the daemons cannot run here: the reason, then the logs' last lines
  echo "$script_name: cannot start Slurm: $*" >&2
  local f
  for f in "$dir"/munge/munged.log "$dir"/log/slurmctld.log "$dir"/log/slurmd.log "$dir"/log/*.stderr; do
    [ -s "$f" ] || continue
    echo "--- last lines of $f:" >&2
    tail -n 8 "$f" >&2
  done
  stop
  exit 3
}

# Stops the daemon whose pid file is FILE: TERM, up to 10 s, then KILL.
stop_daemon() {
  local file="$1" pid
  [ -f "$file" ] || return 0
  pid="$(cat "$file" 2>/dev/null || true)"
  [[ "$pid" =~ ^[0-9]+$ ]] || return 0
  kill -TERM "$pid" 2>/dev/null || { rm -f "$file"; return 0; }
  for _ in $(seq 1 100); do
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  kill -KILL "$pid" 2>/dev/null || true
  rm -f "$file"
}

stop() {
  # Jobs first: slurmstepd outlives slurmd, so a job still running would go on without a cluster.
  if [ -f "$dir/slurmctld.pid" ] && [ -f "$dir/slurm.conf" ]; then
    SLURM_CONF="$dir/slurm.conf" timeout 10 scancel --quiet --user="$(id -un)" 2>/dev/null || true
    for _ in $(seq 1 20); do
      [ -z "$(SLURM_CONF="$dir/slurm.conf" timeout 5 squeue -h 2>/dev/null)" ] && break
      sleep 0.5
    done
  fi
  stop_daemon "$dir/slurmd.pid"
  stop_daemon "$dir/slurmctld.pid"
  stop_daemon "$dir/munge/munged.pid"
}

# Ports nobody listens on now (the kernel's pick), so two clusters or a real one cannot collide.
free_ports() {
  local python=python3
  command -v "$python" >/dev/null || python=/usr/bin/python3
  "$python" - <<'EOF'
import socket
socks = [socket.socket() for _ in range(2)]
for s in socks:
    s.bind(("127.0.0.1", 0))
print(" ".join(str(s.getsockname()[1]) for s in socks))
EOF
}

start() {
  local bin
  for bin in munged slurmctld slurmd sbatch squeue sinfo; do
    command -v "$bin" >/dev/null || PATH="$PATH:/usr/sbin"
    command -v "$bin" >/dev/null ||
      cannot_run "'$bin' not found (the Debian packages slurm-wlm and munge: bash scripts/install_deps.sh --tests)"
  done
  mkdir -p "$dir"
  dir="$(cd "$dir" && pwd)"
  # munged insists that every folder above its socket be traversable by all, and its key be private.
  chmod 755 "$dir"
  local up="$dir"
  while [ "$up" != / ]; do
    up="$(dirname "$up")"
    [ "$(( 0$(stat -c %a "$up") & 1 ))" -eq 1 ] ||
      die "$up is not traversable by all (chmod o+x, or choose a folder elsewhere): munged refuses such a socket path"
  done
  mkdir -p "$dir/munge" "$dir/munge/key" "$dir/state" "$dir/spool" "$dir/log"
  chmod 755 "$dir/munge"
  chmod 700 "$dir/munge/key"
  head -c 1024 /dev/urandom >"$dir/munge/key/munge.key"
  chmod 600 "$dir/munge/key/munge.key"
  local socket="$dir/munge/munge.socket"
  munged --key-file="$dir/munge/key/munge.key" --socket="$socket" --pid-file="$dir/munge/munged.pid" \
    --log-file="$dir/munge/munged.log" --seed-file="$dir/munge/munged.seed" 2>"$dir/log/munged.stderr" ||
    cannot_run "munged did not start"
  munge -n -S "$socket" | unmunge -S "$socket" >/dev/null 2>&1 ||
    cannot_run "munged runs but a credential does not round-trip through $socket"

  local user node hw ctld_port slurmd_port
  user="$(id -un)"
  node="$(hostname -s)"
  # The node as slurmd sees it (CPUs, sockets, memory), so the controller does not drain it as misconfigured.
  hw="$(slurmd -C 2>/dev/null | head -n 1 | sed 's/^NodeName=[^ ]* //')"
  [[ "$hw" == *CPUs=* ]] || cannot_run "'slurmd -C' did not describe this node"
  read -r ctld_port slurmd_port <<<"$(free_ports)"
  cat >"$dir/slurm.conf.tmp" <<EOF
# Written by $script_name: a single-node cluster on localhost, everything under $dir.
ClusterName=watergs-local
SlurmctldHost=$node(127.0.0.1)
SlurmUser=$user
SlurmdUser=$user
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
# No cgroups (containers without systemd have none to delegate): processes tracked through /proc.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
# A one-node cluster: look at pending jobs every 2 s (default 60) so that a job whose dependency
# ended starts at once.
SchedulerParameters=sched_interval=2,bf_interval=1
ReturnToService=2
MinJobAge=600
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=$node NodeAddr=127.0.0.1 $hw State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
  mv "$dir/slurm.conf.tmp" "$dir/slurm.conf"
  export SLURM_CONF="$dir/slurm.conf"
  slurmctld -i 2>"$dir/log/slurmctld.stderr" || cannot_run "slurmctld did not start"
  slurmd -N "$node" 2>"$dir/log/slurmd.stderr" || cannot_run "slurmd did not start"
  local state=""
  for _ in $(seq 1 60); do
    state="$(sinfo -h -n "$node" -o %t 2>/dev/null || true)"
    [[ "$state" =~ ^(idle|mix|alloc) ]] && break
    sleep 0.5
  done
  [[ "$state" =~ ^(idle|mix|alloc) ]] || cannot_run "node $node is '${state:-unknown}' after 30 s, not idle"
  echo "export SLURM_CONF=$dir/slurm.conf"
}

[ $# -eq 2 ] || die "usage: $script_name start|stop DIR"
dir="$2"
case "$1" in
  start) start ;;
  stop) [ -d "$dir" ] || die "$dir: no such folder"; stop ;;
  *) die "usage: $script_name start|stop DIR" ;;
esac
