# cluster.sh - sourced by tests/farm/slurm.sh and bench/bench_farm.sh: a
# single-node Slurm cluster on localhost, in a folder of its own (munged,
# slurmctld and slurmd with their keys, state, logs and pid files there, on
# random ports), so that nothing of the machine's own Slurm or munge is used
# or touched. Needs root, slurm-wlm and munge (./setup.sh farm-test).
#
#   start_cluster DIR CPUS   start it, its node declaring CPUS processors;
#                            SLURM_CONF exported; returns 1 (the logs on
#                            stderr) when the node is not idle in 10 s
#   stop_cluster             stop the running one (none: nothing to do)

cl=
stop_cluster() {
  [ -n "$cl" ] || return 0
  for f in "$cl/slurmd.pid" "$cl/slurmctld.pid" "$cl/munge/pid"; do
    [ -f "$f" ] && kill "$(cat "$f")" 2>/dev/null || true
  done
  for _ in $(seq 50); do
    pgrep -F "$cl/slurmctld.pid" >/dev/null 2>&1 || pgrep -F "$cl/slurmd.pid" >/dev/null 2>&1 || break
    sleep 0.1
  done
  cl=
}

start_cluster() {
  cl=$1
  mkdir -p "$cl/munge" "$cl/ctld" "$cl/d" "$cl/log"
  mungekey -c -k "$cl/munge/munge.key" >/dev/null 2>&1
  chmod 600 "$cl/munge/munge.key"
  munged --force -S "$cl/munge/socket" --key-file="$cl/munge/munge.key" --pid-file="$cl/munge/pid" \
    --log-file="$cl/munge/log" --seed-file="$cl/munge/seed"
  local base=$((20000 + RANDOM % 40000)) host
  host=$(hostname -s)
  cat > "$cl/slurm.conf" <<CONF
ClusterName=seamcook
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$base
SlurmdPort=$((base + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$cl/munge/socket
CredType=cred/munge
StateSaveLocation=$cl/ctld
SlurmdSpoolDir=$cl/d
SlurmctldPidFile=$cl/slurmctld.pid
SlurmdPidFile=$cl/slurmd.pid
SlurmctldLogFile=$cl/log/slurmctld.log
SlurmdLogFile=$cl/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
NodeName=$host NodeAddr=127.0.0.1 CPUs=$2 State=UNKNOWN
PartitionName=farm Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
  export SLURM_CONF=$cl/slurm.conf
  slurmctld -c -i
  slurmd -N "$host"
  for _ in $(seq 100); do sinfo --noheader -o %t 2>/dev/null | grep -q idle && break; sleep 0.1; done
  sinfo --noheader -o %t | grep -q idle || { cat "$cl/log/"* >&2; echo "the cluster did not come up" >&2; return 1; }
  [ "$(sinfo --noheader -o %c)" = "$2" ] || { echo "the node has $(sinfo --noheader -o %c) CPUs, not $2" >&2; return 1; }
}
