#!/bin/sh
# Run spm_DEM on every stored data file (needs GNU Octave and SPM12 outside this repository).
#   SPM_ROOT=/work/spm12 sh benchmarks/spm/run_all.sh
set -e
here=$(cd "$(dirname "$0")" && pwd)
root=${SPM_ROOT:-/work/spm12}
for case in lorenz convolution; do
    for data in "$here"/reference/${case}_seed*_data.csv; do
        out=${data%_data.csv}_spm.csv
        octave --no-gui --quiet --eval "spm_root='$root'; data='$data'; out='$out'; run('$here/run_$case.m')" 2>&1 \
            | grep "samples in" || true
    done
done
