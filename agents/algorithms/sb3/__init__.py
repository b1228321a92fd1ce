"""stable-baselines3 on the native vector env: hyperparameters (`.hyperparams`), resumable
training (`.training`), the residual-set-point VecEnv (`.vec_env`), the HER buffer
(`.her`) and saved models as policies (`.policy`)."""
