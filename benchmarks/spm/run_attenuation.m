% SPM reference for attend.control.attenuation: SPM12's sensory-attenuation model (the model of
% ALAP_demo_attenuation, written out here from its stated equations and settings) run through
% spm_ALAP for each attenuation h (the log-precision M(1).hE).
%
%   octave --no-gui --quiet --eval "spm_root='/work/spm12'; run('run_attenuation.m')"
%
% Optional variables: noise (1: the demo's world noise, precision exp(8), rng('default') before
% each run; 0: a noiseless world, precision exp(32)), tag (file-name tag, default
% 'attenuation' or 'attenuation_noiseless'), attenuations (default -4:6), nN (E.nN; default
% spm_ALAP's own, which is 1 here: no parameters or hyperparameters are optimised).
% Writes to reference/:
%   <tag>_spm.csv         one row per h: h, max true force max(pU.x{1}), max perceived
%                         self-generated force max(qU.x{1}(1,:)), CPU and wall seconds of spm_ALAP
%   <tag>_h<h>_spm.csv    one row per time bin: bin, true force pU.x{1}, perceived self and
%                         external force qU.x{1}(1:2,:), action qU.a{2}, perceived causes qU.v{2}
%   <tag>_spm.csv.json    settings, Octave version, total CPU seconds
crash_dumps_octave_core(false);
addpath(spm_root); addpath(fullfile(spm_root, 'toolbox', 'DEM'));
here = fileparts(mfilename('fullpath'));
addpath(here); addpath(fullfile(here, 'stubs'), fullfile(here, 'stubs_nographics'), '-begin');
if ~exist('noise', 'var'), noise = 1; end
if ~exist('attenuations', 'var'), attenuations = -4:6; end
if ~exist('tag', 'var')
    if noise, tag = 'attenuation'; else, tag = 'attenuation_noiseless'; end
end
if ~exist('outdir', 'var'), outdir = fullfile(here, 'reference'); end
if noise, world_log_precision = 8; else, world_log_precision = 32; end

% the world (generative process): one force x pushed by the action a, sensed twice
G = struct();
G(1).E.d = 2; G(1).E.n = 4;
G(1).f = @(x, v, a, P) tanh(a) - x/4;
G(1).g = @(x, v, a, P) [x; v + x];
G(1).x = 0; G(1).v = [0; 0];
G(1).V = exp(world_log_precision);
G(1).W = exp(world_log_precision);
G(1).U = [1 0];                          % reflex precision: proprioception only
G(2).v = 0; G(2).a = 0; G(2).V = exp(16);

% the agent (generative model): a self-generated force x1 and an external one x2
M = struct();
M(1).E.d = 2; M(1).E.n = 4; M(1).E.s = 1/2;
M(1).E.method.x = 1; M(1).E.method.v = 1;   % precision depends on states and causes
M(1).E.method.h = 0; M(1).E.method.g = 0;   % no optimisation of h, g
if exist('nN', 'var'), M(1).E.nN = nN; end
M(1).f = @(x, v, P) v - x/4;
M(1).g = @(x, v, P) [x(1); x(1) + x(2)];
M(1).x = [0; 0]; M(1).v = [0; 0];
M(1).W = exp(4);
M(1).ph = @(x, v, h, M) [1; 1] * (8 - h * tanh(v(1) + x(1)));
M(1).hE = 6;
M(2).v = [0; 0]; M(2).V = [exp(6); exp(0)];

N = 32;
prior = zeros(2, N);
prior(1, :) = exp(-((1:N) - N/2).^2 / 4^2);   % intended push, peak at bin 16

DEM = struct('M', M, 'G', G, 'C', zeros(1, N), 'U', prior);
summary = zeros(numel(attenuations), 5);
for i = 1:numel(attenuations)
    h = attenuations(i);
    rng('default');
    LAP = DEM;
    LAP.M(1).hE = h;
    tic; cpu0 = cputime;
    LAP = spm_ALAP(LAP);
    wall = toc; cpu = cputime - cpu0;
    true_force = full(LAP.pU.x{1}(1, :));
    belief = full(LAP.qU.x{1});
    summary(i, :) = [h, max(true_force), max(belief(1, :)), cpu, wall];
    trace = [(1:N)', true_force', belief', full(LAP.qU.a{2})', full(LAP.qU.v{2})'];
    dlmwrite(fullfile(outdir, sprintf('%s_h%d_spm.csv', tag, h)), trace, 'delimiter', ',', 'precision', '%.17g');
    printf('h = %2d: true %.4f perceived %.4f (%.2f s CPU)\n', h, summary(i, 2), summary(i, 3), cpu);
end
out = fullfile(outdir, [tag '_spm.csv']);
if exist('nN', 'var'), nN_text = num2str(nN); else, nN_text = 'default (1: nothing to optimise)'; end
dlmwrite(out, summary, 'delimiter', ',', 'precision', '%.17g');
fid = fopen([out '.json'], 'w');
fprintf(fid, ['{"routine": "spm_ALAP", "bins": %d, "attenuations": [%s], "world_log_precision": %g, ' ...
              '"rng_default_each_run": %d, "E_nN": "%s", "cpu_seconds_total": %.4f, ' ...
              '"cpu_seconds_per_run": %.4f, "wall_seconds_total": %.4f, "octave": "%s"}\n'], ...
        N, strjoin(arrayfun(@num2str, attenuations, 'UniformOutput', false), ', '), world_log_precision, ...
        noise, nN_text, sum(summary(:, 4)), mean(summary(:, 4)), sum(summary(:, 5)), OCTAVE_VERSION);
fclose(fid);
