function varargout = set(varargin)
% No-op stand-in for Octave's graphics function set: spm_ALAP and spm_ADEM plot their progress
% directly (not only through spm_figure/spm_DEM_qU), and a headless Octave has no graphics
% toolkit. Used only by the drivers of the active-inference references (run_attenuation.m,
% run_reaching.m), never on the path of the spm_DEM drivers.
varargout = cell(1, nargout);   % nothing is drawn; outputs (a handle) are empty
end
