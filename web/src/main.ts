// Entry point of the studio page.
import './style.css';
import { Studio } from './app/Studio';
import { installTestHook } from './testing/TestHook';

const root = document.getElementById('app') as HTMLElement;
const studio = new Studio(root);
installTestHook(studio);
studio.start();
