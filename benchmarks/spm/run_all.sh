#!/bin/sh
# Run spm_DEM on every stored data file (needs GNU Octave and SPM12 outside this repository).
#   SPM_ROOT=/work/spm12 sh benchmarks/spm/run_all.sh
set -e
here=$(cd "$(dirname "$0")" && pwd)
root=${SPM_ROOT:-/work/spm12}
linear=${SPM_LINEAR:-0}
for data in "$here"/reference/lorenz_seed*_data.csv; do
    out=${data%_data.csv}_spm.csv
    octave --no-gui --quiet --eval "spm_root='$root'; data='$data'; out='$out'; linear=$linear; run('$here/run_lorenz.m')" 2>&1 \
        | grep -v -e "^warning" -e "called from" -e "^ *spm_\|^ *run" -e "^ans" -e "^$" -e "preparing to exit" || true
done
