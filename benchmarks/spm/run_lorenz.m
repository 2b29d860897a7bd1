% SPM reference for attend's Lorenz case: spm_DEM's D-step on data simulated by attend.
%
%   octave --no-gui --eval "spm_root='/work/spm12'; data='in.csv'; out='out.csv'; run('run_lorenz.m')"
%
% data: CSV, one row per sample: y1 y2 y3 (outputs) x1 x2 x3 (true states, unused here).
% out:  CSV, one row per sample: qU.x{1}' (SPM's conditional mean of the states at that bin),
%       and out.json: samples, wall and CPU seconds, samples per CPU second, Octave version.
% SPM works in time bins: f is attend's f [1/s] times dt, W is attend's Pi_w [s^2] / dt^2,
% E.s is attend's kernel_width / dt. Only the D-step runs: parameters and precisions fixed.
crash_dumps_octave_core(false);                 % no octave-workspace file on exit
addpath(spm_root); addpath(fullfile(spm_root, 'toolbox', 'DEM'));
here = fileparts(mfilename('fullpath'));
addpath(here); addpath(fullfile(here, 'stubs'), '-begin');   % run_spm_dem; headless: no figures
if ~exist('dt', 'var'), dt = 0.01; end                 % attend's sample time [s]
if ~exist('kernel_width', 'var'), kernel_width = 0.02; end
if ~exist('process_std', 'var'), process_std = 20; end % [state unit / s]
if ~exist('measurement_std', 'var'), measurement_std = 1; end
if ~exist('order', 'var'), order = 6; end
D = dlmread(data, ',');
Y = D(:, 1:3)';

lorenz_dt = @(x, v, P) dt * [P(1)*(x(2) - x(1)); x(1)*(P(2) - x(3)) - x(2); x(1)*x(2) - P(3)*x(3)];
M = struct();
M(1).E.s = kernel_width / dt;          % smoothness in bins
M(1).E.n = order;                      % embedding order of states and data
M(1).E.d = order;                      % embedding order of causes (pinned here)
M(1).E.nD = 1;                         % one D-step per bin
M(1).E.nE = 1; M(1).E.nM = 1; M(1).E.nN = 1;
if ~exist('linear', 'var'), linear = 0; end
M(1).E.linear = linear;             % 0: SPM's full evaluation of the derivatives
M(1).f = lorenz_dt;
M(1).g = @(x, v, P) x;
M(1).x = Y(:, 1);                      % start at the first observation
M(1).pE = [10; 28; 8/3];
M(1).pC = sparse(3, 3);                % parameters fixed
M(1).V = eye(3) / measurement_std^2;   % Pi_z: fixed precision, no hyperparameters
M(1).W = eye(3) / (process_std * dt)^2; % Pi_w in bins: w_bin = dt * w
M(2).v = 0;                            % an autonomous system: one dummy cause pinned at 0
M(2).V = exp(16);
run_spm_dem(M, Y, out, false);
