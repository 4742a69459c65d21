#!/usr/bin/env bash
# A single-node SLURM cluster on this machine (as root, no systemd), for the
# cluster integration test: `bash .ci/slurm.sh start` / `bash .ci/slurm.sh stop`.
# What each step needs is in docs/slurm.md.
set -euo pipefail

start() {
  if ! command -v slurmctld >/dev/null 2>&1; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
      slurmctld slurmd slurm-client munge >/dev/null
  fi
  mkdir -p /run/munge /var/spool/slurmctld /var/spool/slurmd /etc/slurm
  chown munge:munge /run/munge /etc/munge/munge.key
  chmod 0755 /run/munge
  chmod 0400 /etc/munge/munge.key
  if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
    runuser -u munge -- munged
  fi
  local host node
  host=$(hostname -s)
  node=$(slurmd -C | head -n 1)
  cat > /etc/slurm/slurm.conf <<CONF
ClusterName=sigmap
SlurmctldHost=${host}(127.0.0.1)
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerParameters=batch_sched_delay=0
MailProg=/bin/true
ReturnToService=2
SlurmUser=root
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
${node} NodeAddr=127.0.0.1
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
  [ -f /run/slurmctld.pid ] && kill -0 "$(cat /run/slurmctld.pid)" 2>/dev/null || slurmctld
  [ -f /run/slurmd.pid ] && kill -0 "$(cat /run/slurmd.pid)" 2>/dev/null || slurmd
  for _ in $(seq 1 100); do
    state=$(sinfo -h -o %T 2>/dev/null | head -n 1 || true)
    if [ "$state" = "idle" ] || [ "$state" = "mixed" ]; then
      echo "slurm: node $state"
      return 0
    fi
    sleep 0.2
  done
  echo "slurm: the node did not come up (state '${state:-none}')" >&2
  return 1
}

stop() {
  for pid in /run/slurmd.pid /run/slurmctld.pid /run/munge/munged.pid; do
    if [ -f "$pid" ]; then
      kill "$(cat "$pid")" 2>/dev/null || true
    fi
  done
}

"${1:-start}"
