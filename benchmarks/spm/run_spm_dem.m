function DEM = run_spm_dem(M, Y, out, with_inputs)
% Run spm_DEM on data Y (outputs x samples) with model M and the prior U = 0; write the
% conditional means, one row per sample, to the CSV file out: qU.x{1}' (and qU.v{2}', the
% estimated inputs, when with_inputs), and out.json: samples, wall and CPU seconds of the
% spm_DEM call, samples per CPU second, Octave version, E.linear.
N = size(Y, 2);
DEM.M = M;
DEM.Y = Y;
DEM.U = zeros(1, N);
tic; cpu0 = cputime;
DEM = spm_DEM(DEM);
elapsed = toc; cpu = cputime - cpu0;
estimates = full(DEM.qU.x{1})';
if with_inputs
    estimates = [estimates full(DEM.qU.v{2})'];
end
dlmwrite(out, estimates, 'delimiter', ',', 'precision', '%.17g');
fid = fopen([out '.json'], 'w');
fprintf(fid, '{"samples": %d, "wall_seconds": %.4f, "cpu_seconds": %.4f, "samples_per_second": %.2f, "octave": "%s", "E_linear": %d}\n', ...
        N, elapsed, cpu, N / cpu, OCTAVE_VERSION, M(1).E.linear);
fclose(fid);
printf('%d samples in %.2f s CPU (%.1f samples/s; wall %.2f s)\n', N, cpu, N / cpu, elapsed);
end
