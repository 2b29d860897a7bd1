% SPM reference for attend.control.reaching: SPM12's reaching model (the model of ADEM_reaching,
% written out here from its stated settings; the arm's flow and output are SPM's own files
% spm_fx_dem_reach / spm_gx_dem_reach (agent) and spm_fx_adem_reach / spm_gx_adem_reach (world),
% called by name from the SPM path) run through spm_ADEM.
%
%   octave --no-gui --quiet --eval "spm_root='/work/spm12'; run('run_reaching.m')"
%
% Optional variables: cued (1: the demo's cue; 0: no cue, the control condition), noise (1: the
% demo's world noise, precision exp(16), rng('default') first; 0: a noiseless world, exp(32)),
% N (bins, default 128), tag (file-name tag, default 'reaching[_nocue][_noiseless]').
% Writes to reference/:
%   <tag>_spm.csv       one row per time bin: bin, true joint angles and velocities pU.x{1}
%                       (4), true finger (2), believed angles qU.x{1}(1:2), believed finger
%                       (2), action qU.a{2} (2), believed causes qU.v{2} (3)
%   <tag>_spm.csv.json  bins, CPU and wall seconds of the spm_ADEM call, Octave version
crash_dumps_octave_core(false);
addpath(spm_root); addpath(fullfile(spm_root, 'toolbox', 'DEM'));
here = fileparts(mfilename('fullpath'));
addpath(here); addpath(fullfile(here, 'stubs'), fullfile(here, 'stubs_nographics'), '-begin');
if ~exist('cued', 'var'), cued = 1; end
if ~exist('noise', 'var'), noise = 1; end
if ~exist('N', 'var'), N = 128; end
if ~exist('tag', 'var')
    tag = 'reaching';
    if ~cued, tag = [tag '_nocue']; end
    if ~noise, tag = [tag '_noiseless']; end
end
if ~exist('outdir', 'var'), outdir = fullfile(here, 'reference'); end
if noise, world_log_precision = 16; else, world_log_precision = 32; end

% the agent: arm pulled to the target with the cue's strength; sees angles, causes and finger
M = struct();
M(1).E.s = 1/2; M(1).E.n = 4; M(1).E.d = 2;
M(1).f = 'spm_fx_dem_reach';
M(1).g = 'spm_gx_dem_reach';
M(1).x = [pi/2; pi/2; 0; 0];
M(1).V = exp(8); M(1).W = exp(8);
M(2).v = [0; 0; 0]; M(2).V = exp(0);

% the world: the damped arm with a spring to rest, moved by two torques
G = M;
G(1).f = 'spm_fx_adem_reach';
G(1).g = 'spm_gx_adem_reach';
G(1).V = exp(world_log_precision); G(1).W = exp(world_log_precision);
G(1).U = exp(8);                          % reflex precision, every output
G(2).v = [0; 0; 0]; G(2).a = [0; 0]; G(2).V = exp(16);

C = zeros(3, N);
C(1, :) = 0.6; C(2, :) = 0.6;                            % target
C(3, :) = cued * exp(-((1:N) - 32).^2 / 8^2);             % cue, peak at bin 32
M(2).v = C(:, 1);

DEM = struct('G', G, 'M', M, 'C', sparse(C), 'U', sparse(3, N));
DEM.db = 0;                               % spm_ADEM: no progress figures
rng('default');
tic; cpu0 = cputime;
DEM = spm_ADEM(DEM);
wall = toc; cpu = cputime - cpu0;

x = full(DEM.pU.x{1}); q = full(DEM.qU.x{1});
finger = @(th) [cos(th(1, :)) - cos(th(1, :) + th(2, :)); sin(th(1, :)) - sin(th(1, :) + th(2, :))];
trace = [(1:N)', x', finger(x(1:2, :))', q(1:2, :)', finger(q(1:2, :))', full(DEM.qU.a{2})', full(DEM.qU.v{2})'];
out = fullfile(outdir, [tag '_spm.csv']);
dlmwrite(out, trace, 'delimiter', ',', 'precision', '%.17g');
fid = fopen([out '.json'], 'w');
fprintf(fid, ['{"routine": "spm_ADEM", "bins": %d, "cued": %d, "world_log_precision": %g, ' ...
              '"cpu_seconds": %.4f, "wall_seconds": %.4f, "octave": "%s"}\n'], N, cued, world_log_precision, cpu, wall, OCTAVE_VERSION);
fclose(fid);
d = sqrt(sum((finger(x(1:2, :)) - 0.6).^2, 1));
printf('%d bins in %.2f s CPU (wall %.2f s); closest finger-target distance %.4f at bin %d, final %.4f\n', ...
       N, cpu, wall, min(d), find(d == min(d), 1), d(end));
