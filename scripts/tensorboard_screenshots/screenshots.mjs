// Screenshots of TensorBoard's IMAGES and HPARAMS tabs for the docs (docs/usage.md, "What TensorBoard shows").
// Run by scripts/tensorboard_screenshots/make.sh, which trains the runs and serves TensorBoard at $TB_URL.
// A headless Chromium from npm (@sparticuz/chromium, driven by puppeteer-core): no browser needs to be installed.
import chromium from '@sparticuz/chromium';
import puppeteer from 'puppeteer-core';

const url = process.env.TB_URL || 'http://localhost:6006';
const out = process.env.OUT_DIR || '.';
// The HPARAMS table shows the first five settings by default; these are the ones the docs compare
const shown = new Set(['algo', 'seed', 'gamma', 'eval/mean_reward', 'eval/coverage',
  'eval/fairness', 'eval/energy', 'eval/energy_efficiency']);
const columns = new Set([...shown, 'env', 'n_timesteps', 'actor_learning_rate', 'actor_reg', 'batch_size', 'buffer_size', 'critic_warmup_steps',
  'cvar_alpha', 'env_kwargs', 'gradient_steps', 'learning_rate', 'learning_starts', 'max_grad_norm', 'n_envs',
  'noise_decay', 'noise_final_std', 'noise_std', 'noise_type', 'policy', 'policy_delay', 'policy_kwargs',
  'target_policy_noise', 'tau', 'train_freq', 'eval/mean_ep_length', 'rollout/ep_rew_mean']);

const settle = () => new Promise((resolve) => setTimeout(resolve, 3000));
const browser = await puppeteer.launch({ args: chromium.args, executablePath: await chromium.executablePath(), headless: true });
try {
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height: 820 });
  await page.goto(`${url}/#images`, { waitUntil: 'networkidle0', timeout: 60000 });
  await settle();
  await page.screenshot({ path: `${out}/tensorboard_images.png` });

  await page.setViewport({ width: 2100, height: 820 });
  await page.goto(`${url}/#hparams`, { waitUntil: 'networkidle0', timeout: 60000 });
  await settle();
  for (const box of await page.$$('pierce/paper-checkbox')) {
    const [name, checked] = await box.evaluate((element) => [element.textContent.trim(), element.checked]);
    if (columns.has(name) && checked !== shown.has(name)) await box.click();
  }
  await settle();
  await page.screenshot({ path: `${out}/tensorboard_hparams.png`, clip: { x: 0, y: 0, width: 2100, height: 250 } });
} finally {
  await browser.close();
}
