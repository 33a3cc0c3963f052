function n_failed = run_vectors(vectors_dir)
% RUN_VECTORS  Test script of the Octave port: every case of the shared vector files.
%
%   run_vectors(vectors_dir) reads <vectors_dir>/<problem>.json with jsondecode for the problems
%   kalman_cv2d, white_noise_q, projection_jacobian and variational_scene_flow, runs the port on
%   each case and prints one line per case:
%       CASE <problem> <id> PASS|FAIL <max_abs_err> <message>
%   A case passes iff every |got - expected| <= atol + rtol * |expected|. Returns the number of
%   failed cases.
  problems = {'kalman_cv2d', 'white_noise_q', 'projection_jacobian', 'variational_scene_flow'};
  n_failed = 0;
  for p = 1:numel(problems)
    problem = problems{p};
    file = fullfile(vectors_dir, [problem '.json']);
    if ~exist(file, 'file')
      printf('CASE %s - FAIL nan vector file %s.json missing\n', problem, problem);
      n_failed = n_failed + 1;
      continue;
    end
    doc = jsondecode(fileread(file));
    cases = doc.cases;
    if isstruct(cases), cases = num2cell(cases); end  % equal-field cases decode to a struct array
    for c = 1:numel(cases)
      cs = cases{c};
      try
        [ok, err, msg] = run_case(problem, cs.input, cs.expected, cs.rtol, cs.atol);
      catch e
        ok = false; err = NaN; msg = strrep(e.message, sprintf('\n'), ' ');
      end
      if ok, word = 'PASS'; else, word = 'FAIL'; n_failed = n_failed + 1; end
      printf('CASE %s %s %s %.17g %s\n', problem, cs.id, word, err, msg);
    end
  end
end

function [ok, err, msg] = run_case(problem, in, ex, rtol, atol)
  switch problem
    case 'kalman_cv2d'
      [pos, P] = kalman_cv2d(in.measurements, in.dt, in.process_var, in.meas_var, in.x0, in.P0);
      [ok1, e1, m1] = compare('positions', pos, ex.positions, rtol, atol);
      [ok2, e2, m2] = compare('P_final', P, ex.P_final, rtol, atol);
      ok = ok1 && ok2; err = max(e1, e2); msg = strtrim([m1 ' ' m2]);
    case 'white_noise_q'
      [ok, err, msg] = compare('Q', white_noise_q(in.dt, in.q, in.dim), ex.Q, rtol, atol);
    case 'projection_jacobian'
      [ok, err, msg] = compare('J', projection_jacobian(in.X, in.fx, in.fy, in.cx, in.cy), ex.J, rtol, atol);
    case 'variational_scene_flow'
      a = grids(in.a); b = grids(in.b); v_ex = grids(ex.v);
      ok = true; err = 0; msg = '';
      for k = 1:numel(a)
        v = variational_component(a{k}, b{k}, in.dt, in.lam);
        [okk, ek, mk] = compare(sprintf('v[%d]', k - 1), v, v_ex{k}, rtol, atol);
        ok = ok && okk; err = max(err, ek); msg = strtrim([msg ' ' mk]);
      end
    otherwise
      error('problem %s not implemented', problem);
  end
  if ok, msg = 'ok'; end
end

function g = grids(arr)
  % (C, H, W) nested lists -> cell array of C matrices H x W
  if ndims(arr) == 3
    g = cell(1, size(arr, 1));
    for k = 1:size(arr, 1)
      g{k} = reshape(arr(k, :, :), size(arr, 2), size(arr, 3));
    end
  else
    g = {arr};
  end
end

function [ok, err, msg] = compare(name, got, ex, rtol, atol)
  msg = '';
  if ~isequal(size(got), size(ex))
    ok = false; err = NaN;
    msg = sprintf('%s: shape %s, expected %s', name, mat2str(size(got)), mat2str(size(ex)));
    return;
  end
  d = abs(got - ex);
  d(isnan(d)) = Inf;
  err = max([d(:); 0]);
  bad = find(d > atol + rtol * abs(ex), 1);
  ok = isempty(bad);
  if ~ok
    msg = sprintf('%s(%d): got %.17g, expected %.17g', name, bad, got(bad), ex(bad));
  end
end
