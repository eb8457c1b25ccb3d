set terminal pngcairo size 820,600 font 'sans,11'
set output 'error_experiment2_limiter.png'
set datafile separator ','
set logscale xy
set format x '10^{%L}'
set format y '10^{%L}'
set xlabel 'wall time of the run [s]'
set ylabel 'error: RMS distance to the reference / grid spacing'
set title 'Experiment II (30 x 60 tablecloth onto a desk), stress-ordered limiter'
set key bottom left font ',10'
set grid
set yrange [*:120]
plot 'error_experiment2_limiter.csv' using 3:(strcol(1) eq 'explicit_euler' && strcol(6) eq 'no' ? $5 : 1/0) w lp pt 11 lc rgb '#d62728' t 'explicit Euler', \
     'error_experiment2_limiter.csv' using 3:(strcol(1) eq 'symplectic_euler' && strcol(6) eq 'no' ? $5 : 1/0) w lp pt 5 lc rgb '#1f77b4' t 'symplectic Euler', \
     'error_experiment2_limiter.csv' using 3:(strcol(1) eq 'velocity_verlet' && strcol(6) eq 'no' ? $5 : 1/0) w lp pt 7 lc rgb '#2ca02c' t 'Velocity-Verlet', \
     'error_experiment2_limiter.csv' using 3:(strcol(1) eq 'rk4' && strcol(6) eq 'no' ? $5 : 1/0) w lp pt 9 lc rgb '#9467bd' t 'RK4', \
     'error_experiment2_limiter.csv' using 3:(strcol(1) eq 'implicit_euler' && strcol(6) eq 'no' ? $5 : 1/0) w lp pt 13 lc rgb '#ff7f0e' t 'implicit Euler', \
     'error_experiment2_limiter.csv' using 3:(strcol(6) eq 'yes' ? 30 : 1/0) w p pt 2 ps 2.5 lw 2 lc rgb '#000000' t 'unstable (blew up or diverged)'
