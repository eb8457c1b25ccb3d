set terminal pngcairo size 900,760 font 'sans,11'
set output 'stability_vs_stiffness.png'
set datafile separator ','
set logscale xy
set format x '10^{%L}'
set format y '10^{%L}'
set xlabel 'spring stiffness k [N/m]'
set ylabel 'largest stable time step [s]'
set title 'Largest stable dt against stiffness (hanging sheet, m = 0.5, spacing 10)'
set key below maxcols 2 font ',10'
set grid
plot 'stability_vs_stiffness.csv' using 2:(strcol(1) eq 'symplectic_euler' ? $8 : 1/0) w lp pt 5 lc rgb '#1f77b4' t 'symplectic Euler, measured', \
 '' using 2:(strcol(1) eq 'velocity_verlet' ? $8 : 1/0) w lp pt 7 lc rgb '#2ca02c' t 'Velocity-Verlet, measured', \
 '' using 2:(strcol(1) eq 'rk4' ? $8 : 1/0) w lp pt 9 lc rgb '#9467bd' t 'RK4, measured', \
 '' using 2:(strcol(1) eq 'explicit_euler' ? $8 : 1/0) w lp pt 11 lc rgb '#d62728' t 'explicit Euler, measured', \
 '' using 2:(strcol(1) eq 'implicit_euler' ? $8 : 1/0) w p pt 8 ps 1.6 lc rgb '#ff7f0e' t 'implicit Euler: stable at every dt tried (largest shown)', \
 '' using 2:(strcol(1) eq 'velocity_verlet' ? 2/$3 : 1/0) w l dt 2 lw 2 lc rgb '#2ca02c' t '2 / omega_{max} (drape bound)', \
 '' using 2:(strcol(1) eq 'velocity_verlet' ? 2/$4 : 1/0) w l dt 3 lw 2 lc rgb '#000000' t '2 / omega_{max} (exact, at rest)', \
 '' using 2:(strcol(1) eq 'rk4' ? 2.785/$3 : 1/0) w l dt 2 lw 2 lc rgb '#9467bd' t '2.785 / omega_{max} (RK4, bound)', \
 '' using 2:(strcol(1) eq 'explicit_euler' ? $6 : 1/0) w l dt 4 lw 2 lc rgb '#d62728' t 'explicit Euler C_d / (m omega^2) (asymptotic)', \
 '' using 2:(strcol(1) eq 'explicit_euler' ? $7 : 1/0) w l dt 5 lw 1 lc rgb '#d62728' t 'explicit Euler, 10^6 growth within the run'
