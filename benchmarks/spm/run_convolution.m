% SPM reference for attend's linear convolution model: spm_DEM's D-step on data simulated by attend.
%
%   octave --no-gui --eval "spm_root='/work/spm12'; data='in.csv'; out='out.csv'; run('run_convolution.m')"
%
% data: CSV, one row per sample: y1..y4 (outputs), x1 x2 (true states), u (true input; unused).
% out:  CSV, one row per sample: qU.x{1}' then qU.v{2}' (SPM's conditional means of the states
%       and of the unknown input), and out.json: samples, wall and CPU seconds, Octave version.
% One sample is one bin (attend's dt = 1 s), so f, s and the precisions carry over unscaled.
% Only the D-step runs: parameters and precisions fixed.
crash_dumps_octave_core(false);                 % no octave-workspace file on exit
addpath(spm_root); addpath(fullfile(spm_root, 'toolbox', 'DEM'));
here = fileparts(mfilename('fullpath'));
addpath(here); addpath(fullfile(here, 'stubs'), '-begin');   % run_spm_dem; headless: no figures
if ~exist('kernel_width', 'var'), kernel_width = 0.5; end   % [bins]
if ~exist('order', 'var'), order = 6; end
if ~exist('log_precision', 'var'), log_precision = 8; end   % Pi_z = Pi_w = exp(8)
if ~exist('prior_log_precision', 'var'), prior_log_precision = -8; end
if ~exist('linear', 'var'), linear = 1; end
if ~exist('input_order', 'var'), input_order = order; end   % E.d (attend's input_order)
D = dlmread(data, ',');
Y = D(:, 1:4)';

A = [-0.25 1; -0.5 -0.25];
B = [1; 0];
C = [0.125 0.1633; 0.125 0.0676; 0.125 -0.0676; 0.125 -0.1633];
M = struct();
M(1).E.s = kernel_width;
M(1).E.n = order;
M(1).E.d = input_order;                % default E.d = E.n (attend's input_order = p)
M(1).E.nD = 1;
M(1).E.nE = 1; M(1).E.nM = 1; M(1).E.nN = 1;
M(1).E.linear = linear;                % 1: SPM's linear model (derivatives once)
M(1).f = @(x, v, P) A * x + B * v;
M(1).g = @(x, v, P) C * x;
M(1).x = [0; 0];
M(1).pE = [];
M(1).V = exp(log_precision);           % Pi_z
M(1).W = exp(log_precision);           % Pi_w
M(2).v = 0;                            % the unknown input, prior mean 0
M(2).V = exp(prior_log_precision);     % its prior precision P_v
run_spm_dem(M, Y, out, true);
