function varargout = spm_figure(varargin)
% No-op stand-in for SPM's figure manager (headless reference runs: nothing is drawn).
varargout = cell(1, max(nargout, 1));
varargout{1} = [];
end
